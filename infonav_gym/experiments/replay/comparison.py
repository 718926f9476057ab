"""Two sweeps of the same experiments under two noise models, side by side, and how greedy's choices moved."""

from __future__ import annotations

from infonav_gym.experiments.replay.tables import budget_cells, table_lines

COMPARED_KEYS = ("position_rmse_m", "mean_nees", "nees_fraction_inside_95", "mean_nis", "nis_inside_95")


def _key(row: dict) -> tuple:
    return row["policy"], row["k"], row["window_s"]


def _mean(value):
    return value["mean"] if isinstance(value, dict) else value


def greedy_choice_change(after_runs: list[dict], before_runs: list[dict]) -> dict:
    """Per greedy budget: the share of (robot, window) pairs in which the chosen targets differ; every window with a
    choice in either counts (the sweeps' clocks may differ by the calibrated offsets, and so a window's candidates)."""
    changes = {}
    before_by_budget = {
        (run["config"]["k"], run["config"]["window_s"]): run
        for run in before_runs
        if run["config"]["policy"] == "greedy"
    }
    for run in after_runs:
        budget = (run["config"]["k"], run["config"]["window_s"])
        if run["config"]["policy"] != "greedy" or budget not in before_by_budget:
            continue
        differing = total = 0
        for robot, metrics in run["robots"].items():
            after, before = _windows(metrics["choices"]), _windows(before_by_budget[budget]["robots"][robot]["choices"])
            windows = after.keys() | before.keys()
            total += len(windows)
            differing += sum(after.get(window) != before.get(window) for window in windows)
        changes[f"k={budget[0]}, window={budget[1]:g} s"] = differing / total if total else None
    return changes


def _windows(choices) -> dict:
    windows: dict[int, list[int]] = {}
    for window, target in choices:
        windows.setdefault(int(window), []).append(int(target))
    return {window: sorted(targets) for window, targets in windows.items()}


def compare(after: dict, before: dict) -> dict:
    """``after`` (the calibrated sweep) beside ``before``: matched rows, the outage, greedy's changed choices."""
    before_rows = {_key(row): row for row in before["rows"]}
    rows = [
        {"policy": row["policy"], "k": row["k"], "window_s": row["window_s"]}
        | {key: {"before": _mean(before_rows[_key(row)][key]), "after": _mean(row[key])} for key in COMPARED_KEYS}
        for row in after["rows"]
        if _key(row) in before_rows
    ]
    comparison = {
        "before_noise": before["config"]["noise"],
        "after_noise": after["config"]["noise"],
        "rows": rows,
        "greedy_choices_changed": greedy_choice_change(after["runs"], before["runs"]),
    }
    if "outage" in after and "outage" in before:
        comparison["outage_ratio"] = {"before": before["outage"]["ratio"], "after": after["outage"]["ratio"]}
    return comparison


def _pair(value: dict, digits: int) -> str:
    cells = [("n/a" if value[side] is None else f"{value[side]:.{digits}f}") for side in ("before", "after")]
    return " → ".join(cells)


def comparison_markdown(comparison: dict) -> str:
    """The comparison as Markdown: one row per policy and budget, ``before → after`` in each cell."""
    header = ["policy", "k", "window [s]", "position RMSE [m]", "mean NEES", "NEES inside 95%", "mean NIS"]
    digits = {"mean_nees": 2, "mean_nis": 2}  # the others: 3
    rows = [
        [row["policy"], *budget_cells(row), *(_pair(row[key], digits.get(key, 3)) for key in COMPARED_KEYS)]
        for row in comparison["rows"]
    ]
    lines = [f"Before ({comparison['before_noise']}) → after ({comparison['after_noise']}):", ""]
    lines += table_lines([*header, "NIS inside 95%"], rows)
    if "outage_ratio" in comparison:
        lines += ["", f"Outage ratio cooperative / landmark-only: {_pair(comparison['outage_ratio'], 3)}."]
    changed = comparison["greedy_choices_changed"]
    if changed:
        cells = ", ".join(f"{budget}: {100 * share:.0f} %" for budget, share in changed.items() if share is not None)
        lines += ["", f"Greedy windows whose chosen landmarks changed with the calibration: {cells}."]
    return "\n".join(lines)
