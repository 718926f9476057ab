"""Registration recall on ``terrain_frame_pair`` pairs: which registration frame pairs use, and control points by it.
Recall (within ``fig6.RECALL_THRESHOLDS_M``) and median error over ``SEED_SETS`` of every candidate with all returns
(``best_candidate``), then of every selector at each of ``BUDGETS`` with ``FRAME_PAIR_ICP``; times cover selection
and ICP (the frames' GICP covariances timed apart), each selector run once untimed first."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from infonav_gym.experiments.reproduce.fig6 import PairRegistration, control_point_count, recall_summary
from infonav_gym.registration.control_points import (
    CONTROL_POINT_STRATEGIES,
    control_point_geometry,
    select_control_points,
)
from infonav_gym.registration.frame_pairs import FRAME_PAIR_ICP, FramePair, terrain_frame_pair
from infonav_gym.rendering import matplotlib_figure, save_figure
from infonav_gym.sensors.ladar import Ladar

SEED_SETS = tuple(range(100 * index, 100 * index + 50) for index in range(5))  # five sets of 50 seeds
BUDGETS = (0.05, 0.10, 0.25, 0.50)  # control points as a fraction of the newer frame's returns
SELECTORS = tuple(strategy for strategy in CONTROL_POINT_STRATEGIES if strategy != "all")
SELECTION_STREAM = 1  # a selector's generator is default_rng((seed, SELECTION_STREAM)), apart from the pair's
KERNEL_EFFICIENCY_SCALES = {"huber": 1.345, "cauchy": 2.385, "tukey": 4.685}  # per unit residual std: 95% efficiency


def candidates() -> dict[str, dict]:
    """Name -> ``icp`` keywords of every registration the table compares (1 m correspondence distance)."""
    residual_std_m = Ladar().range_std_m
    table = {}
    for method in ("point_to_plane", "gicp"):
        table[method] = {"method": method, "max_correspondence_distance": 1.0}
        for kernel, factor in KERNEL_EFFICIENCY_SCALES.items():
            scale = round(factor * residual_std_m, 3)
            table[f"{method} + {kernel} {scale:g} m"] = table[method] | {"robust_kernel": kernel, "kernel_scale": scale}
    return table


def candidate_table(seed_sets=SEED_SETS, progress: bool = False) -> dict[str, list[dict]]:
    """Name -> per seed set, the ``recall_summary`` of each candidate registration with all returns."""
    settings = candidates()

    def pair_errors(seed: int) -> dict[str, float]:
        pair = terrain_frame_pair(np.random.default_rng(seed))
        return {name: PairRegistration(pair, keywords)()["error_after_m"] for name, keywords in settings.items()}

    per_set = _per_set(seed_sets, pair_errors, "registration candidates", progress)
    return {name: [recall_summary([errors[name] for errors in per_pair]) for per_pair in per_set] for name in settings}


def _per_set(seed_sets, play, desc: str, progress: bool) -> list[list]:
    """``play(seed)`` of every seed, a list per seed set, with a progress bar of the pairs."""
    tasks = [(index, seed) for index, seeds in enumerate(seed_sets) for seed in seeds]
    per_set = [[] for _ in seed_sets]
    for index, seed in tqdm(tasks, desc=desc, unit="pair", disable=not progress):
        per_set[index].append(play(seed))
    return per_set


def best_candidate(table: dict[str, list[dict]]) -> str:
    """The name with the highest lowest-over-the-sets 5 cm recall, then mean 5 cm recall, then lowest mean median."""

    def key(name: str) -> tuple[float, float, float]:
        recalls = [row["recall_5cm"] for row in table[name]]
        medians = [row["median_error_after_m"] for row in table[name]]
        return min(recalls), float(np.mean(recalls)), -float(np.mean(medians))

    return max(table, key=key)


def check_budgets(budgets) -> tuple[float, ...]:
    """``budgets`` as a non-empty tuple of distinct fractions in (0, 1], else ``ValueError`` naming the bad one."""
    budgets = tuple(budgets)
    if not budgets:
        raise ValueError("budgets must name at least one fraction of the returns in (0, 1], got none")
    for budget in budgets:
        if isinstance(budget, bool) or not isinstance(budget, (int, float)) or not 0.0 < budget <= 1.0:
            raise ValueError(f"a control-point budget is a fraction of the returns in (0, 1], got {budget!r}")
    if len(set(budgets)) < len(budgets):
        raise ValueError(f"budgets must be distinct, got {budgets}")
    return budgets


def budget_label(budget: float) -> str:
    """A budget as a percentage, the key of its table in the results: 0.05 -> ``"5%"``."""
    return f"{100 * budget:g}%"


def timed_registration(registration: PairRegistration, select=lambda: None) -> dict:
    """Error [m], time [s] and points of ICP of the control points ``select()`` picks (None: all), both timed."""
    start = time.perf_counter()
    result = registration(select())
    return {"error_after_m": result["error_after_m"], "time_s": time.perf_counter() - start, "points": result["points"]}


def pair_runs(seed: int, budgets) -> dict:
    """Every timed registration of ``seed``'s pair: ``{"frame_covariances_s", "all": run, "capped": labels, label:
    {selector: run}}``; ``capped``: the budgets asking for more points than returns with a surface normal (every
    selector then gets that many)."""
    pair = terrain_frame_pair(np.random.default_rng(seed))
    registration = PairRegistration(pair)
    start = time.perf_counter()
    registration.frame_covariances()
    runs = {"frame_covariances_s": time.perf_counter() - start, "all": timed_registration(registration), "capped": []}
    geometry = control_point_geometry(pair.current, pair.motion_covariance)
    with_normal = int(np.count_nonzero(np.isfinite(geometry.error_var_m2)))  # the most the selectors needing one pick
    for budget in budgets:
        label, asked = budget_label(budget), control_point_count(budget, len(registration.source))
        if asked > with_normal:
            runs["capped"].append(label)
        k = min(asked, with_normal)
        runs[label] = {
            selector: timed_registration(registration, _selection(pair, k, selector, seed)) for selector in SELECTORS
        }
    return runs


def _selection(pair: FramePair, k: int, selector: str, seed: int):
    """``selector``'s pick of ``k`` points on ``pair``, to call; ``random`` and ``normal_space`` draw on ``seed``."""
    np_random = np.random.default_rng((seed, SELECTION_STREAM))
    return lambda: select_control_points(
        pair.current, k, selector, pose_covariance=pair.motion_covariance, np_random=np_random
    )


def _load_kernels(seed: int) -> None:
    """Call every selector once on ``seed``'s pair, untimed: a compiled selector's first call loads its kernels."""
    pair = terrain_frame_pair(np.random.default_rng(seed))
    for selector in SELECTORS:
        _selection(pair, 1, selector, seed)()


def control_point_comparison(seed_sets=SEED_SETS, budgets=BUDGETS, progress: bool = False) -> dict:
    """All returns and every selector at every budget with ``FRAME_PAIR_ICP``, per seed set: ``{"budgets",
    "selectors", "frame_covariances_mean_s", "all", "capped_pairs", "by_budget": {label: {selector: ...}}}``."""
    budgets = check_budgets(budgets)
    _load_kernels(seed_sets[0][0])
    per_pair = _per_set(seed_sets, lambda seed: pair_runs(seed, budgets), "control-point selectors", progress)
    labels = [budget_label(budget) for budget in budgets]
    return {
        "budgets": list(budgets),
        "selectors": list(SELECTORS),
        "frame_covariances_mean_s": [
            float(np.mean([runs["frame_covariances_s"] for runs in pairs])) for pairs in per_pair
        ],
        "all": [run_summary([runs["all"] for runs in pairs]) for pairs in per_pair],
        "capped_pairs": {
            label: [sum(label in runs["capped"] for runs in pairs) for pairs in per_pair] for label in labels
        },
        "by_budget": {
            label: {
                selector: [run_summary([runs[label][selector] for runs in pairs]) for pairs in per_pair]
                for selector in SELECTORS
            }
            for label in labels
        },
    }


def run_summary(runs: list[dict]) -> dict:
    """``recall_summary`` of the runs' errors, with their mean points and mean time [s] (and the times)."""
    times = [run["time_s"] for run in runs]
    return {
        **recall_summary([run["error_after_m"] for run in runs]),
        "mean_points": float(np.mean([run["points"] for run in runs])),
        "mean_time_s": float(np.mean(times)),
        "times_s": times,
    }


def registration_recall(seed_sets=SEED_SETS, budgets=BUDGETS, progress: bool = False) -> dict:
    """Both comparisons (module docstring) and the registration chosen, as one JSON-ready dict."""
    budgets = check_budgets(budgets)
    table = candidate_table(seed_sets, progress)
    return {
        "seed_sets": [[seeds[0], seeds[-1]] for seeds in seed_sets],
        "candidates": {name: {"settings": keywords, "sets": table[name]} for name, keywords in candidates().items()},
        "best_by_recall": best_candidate(table),
        "frame_pair_icp": dict(FRAME_PAIR_ICP),
        "control_points": control_point_comparison(seed_sets, budgets, progress),
    }


def recall_markdown(result: dict) -> str:
    """The candidate table and a control-point table per budget as Markdown (recall in %, errors in mm, times in ms)."""
    sets = [f"{first}-{last}" for first, last in result["seed_sets"]]
    header = ["| {} | " + " | ".join(sets) + " |", "| --- |" + " ---: |" * len(sets)]
    lines = [
        "## Registrations, all returns: recall at 5 cm / 10 cm [%], median [mm] (mean [mm]) per seed set",
        "",
        header[0].format("registration"),
        header[1],
    ]
    for name, entry in result["candidates"].items():
        lines.append(f"| {name} | " + " | ".join(_cell(row) for row in entry["sets"]) + " |")
    comparison = result["control_points"]
    covariance_ms = ", ".join(f"{1e3 * seconds:.0f}" for seconds in comparison["frame_covariances_mean_s"])
    lines += [
        "",
        f"Best by recall: `{result['best_by_recall']}`; frame pairs use `{result['frame_pair_icp']}`.",
        "",
        "## Control points with that registration: same cells, then the mean time of selection and ICP [ms]",
        "",
        "Each budget is a fraction of the newer frame's returns; `all` (every return) is the same in every table. "
        f"Not in the times: the frames' GICP covariances, computed once per pair ({covariance_ms} ms per set).",
        "",
        "Pairs on which a budget asked for more points than the newer frame has returns with a surface normal "
        "(every selector then gets that many), per set: "
        + "; ".join(f"{label}: {', '.join(map(str, counts))}" for label, counts in comparison["capped_pairs"].items())
        + ".",
    ]
    for label, selectors in comparison["by_budget"].items():
        lines += ["", f"### {label} of the returns", "", header[0].format("control points"), header[1]]
        for name, per_set in {"all": comparison["all"], **selectors}.items():
            lines.append(f"| {name} | " + " | ".join(f"{_cell(row)}, {_time_ms(row)}" for row in per_set) + " |")
    return "\n".join(lines) + "\n"


def _cell(row: dict) -> str:
    return (
        f"{100 * row['recall_5cm']:.0f} / {100 * row['recall_10cm']:.0f}, "
        f"{1e3 * row['median_error_after_m']:.1f} ({1e3 * row['mean_error_after_m']:.1f})"
    )


def _time_ms(row: dict) -> str:
    return f"{1e3 * row['mean_time_s']:.0f} ms"


_DODGE = 0.2  # how far apart the outermost selectors are drawn at a budget [tick spacing]


def plot_comparison(comparison: dict, path) -> Path:
    """Write ``figure_comparison(comparison)`` to ``path``."""
    return save_figure(figure_comparison(comparison), path, dpi=120)


def figure_comparison(comparison: dict):
    """The selectors' median error (median over the sets, bars min-max) against budget, and against mean time."""
    figure = matplotlib_figure("plotting the control-point comparison", figsize=(13, 5), constrained_layout=True)
    by_budget, against_budget, against_time = comparison["by_budget"], *figure.subplots(1, 2)
    positions = np.arange(len(by_budget), dtype=float)
    every = _set_medians_mm(comparison["all"])
    against_budget.axhline(np.median(every), color="black", linestyle="--", label="all returns")
    against_budget.axhspan(every.min(), every.max(), color="black", alpha=0.08)
    against_time.scatter(
        _mean_time_ms(comparison["all"]), np.median(every), color="black", marker="*", s=120, label="all returns"
    )
    offsets = np.linspace(-_DODGE, _DODGE, len(comparison["selectors"]))
    for offset, selector in zip(offsets, comparison["selectors"]):
        medians = np.array([_set_medians_mm(selectors[selector]) for selectors in by_budget.values()])
        middle = np.median(medians, axis=1)
        spread = [middle - medians.min(axis=1), medians.max(axis=1) - middle]
        bars = against_budget.errorbar(positions + offset, middle, yerr=spread, marker="o", capsize=3, label=selector)
        times = [_mean_time_ms(selectors[selector]) for selectors in by_budget.values()]
        against_time.plot(times, middle, marker="o", color=bars.lines[0].get_color(), label=selector)
        for time_ms, median, label in zip(times, middle, by_budget) if selector == comparison["selectors"][0] else ():
            against_time.annotate(
                label, (time_ms, median), fontsize="x-small", xytext=(3, 3), textcoords="offset points"
            )
    against_budget.set_xticks(positions, list(by_budget))
    against_budget.set(
        xlabel="control points [% of the returns]",
        ylabel="median registration error [mm]",
        title="median error over the pairs (median over the seed sets, bars: min-max)",
    )
    against_time.set(
        xlabel="mean time of selection + ICP [ms]",
        ylabel="median registration error [mm]",
        title="error against time, one marker per selector and budget\n(budgets named on the first selector's line)",
    )
    for axes in (against_budget, against_time):
        axes.grid(True, alpha=0.3)
        axes.legend(fontsize="small")
    return figure


def _set_medians_mm(per_set: list[dict]) -> np.ndarray:
    return 1e3 * np.array([row["median_error_after_m"] for row in per_set])


def _mean_time_ms(per_set: list[dict]) -> float:
    return 1e3 * float(np.mean([row["mean_time_s"] for row in per_set]))
