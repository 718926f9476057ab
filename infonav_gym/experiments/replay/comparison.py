"""Two sweeps of the same experiments under two noise models, side by side."""

from __future__ import annotations

from infonav_gym.experiments.replay.tables import table_lines

COMPARED_KEYS = ("position_rmse_m", "mean_nees", "nees_fraction_inside_95")


def _mean(value):
    return value["mean"] if isinstance(value, dict) else value


def compare(after: dict, before: dict) -> dict:
    """``after`` (the calibrated sweep) beside ``before``: matched rows and the outage."""
    before_rows = {row["policy"]: row for row in before["rows"]}
    rows = [
        {"policy": row["policy"]}
        | {key: {"before": _mean(before_rows[row["policy"]][key]), "after": _mean(row[key])} for key in COMPARED_KEYS}
        for row in after["rows"]
        if row["policy"] in before_rows
    ]
    comparison = {"before_noise": before["config"]["noise"], "after_noise": after["config"]["noise"], "rows": rows}
    if "outage" in after and "outage" in before:
        comparison["outage_ratio"] = {"before": before["outage"]["ratio"], "after": after["outage"]["ratio"]}
    return comparison


def _pair(value: dict, digits: int) -> str:
    cells = [("n/a" if value[side] is None else f"{value[side]:.{digits}f}") for side in ("before", "after")]
    return " → ".join(cells)


def comparison_markdown(comparison: dict) -> str:
    """The comparison as Markdown: one row per policy, ``before → after`` in each cell."""
    header = ["policy", "position RMSE [m]", "mean NEES", "NEES inside 95%"]
    digits = {"mean_nees": 2}  # the others: 3
    rows = [
        [row["policy"], *(_pair(row[key], digits.get(key, 3)) for key in COMPARED_KEYS)] for row in comparison["rows"]
    ]
    lines = [f"Before ({comparison['before_noise']}) → after ({comparison['after_noise']}):", ""]
    lines += table_lines(header, rows)
    if "outage_ratio" in comparison:
        lines += ["", f"Outage ratio cooperative / dead reckoning: {_pair(comparison['outage_ratio'], 3)}."]
    return "\n".join(lines)
