"""Registration recall on ``terrain_frame_pair`` pairs: which registration frame pairs use, and control points by it.

Registration benchmarks judge a method by its *recall* (the fraction of pairs registered within a
threshold, here ``fig6.RECALL_THRESHOLDS_M`` of ``registration_error``) and its median error, which a
diverged pair cannot dominate as it does a mean (kept beside them). Two tables, on ``SEED_SETS``:

- every candidate registration (point-to-plane and GICP, without and with each robust kernel at its
  95%-efficiency scale times the LADAR's range noise) with all returns; ``FRAME_PAIR_ICP`` is the best
  by recall first (the lowest recall over the sets, then the mean recall), then median;
- with ``FRAME_PAIR_ICP``, all returns against a quarter chosen by each control-point strategy (Fig. 6's
  ``seed_statistics``).
"""

from __future__ import annotations

import numpy as np
from tqdm.auto import tqdm

from infonav_gym.experiments.reproduce.fig6 import PairRegistration, recall_summary, seed_statistics
from infonav_gym.registration.frame_pairs import FRAME_PAIR_ICP, terrain_frame_pair
from infonav_gym.sensors.ladar import Ladar

SEED_SETS = tuple(range(100 * index, 100 * index + 50) for index in range(5))  # five sets of 50 seeds
KERNEL_EFFICIENCY_SCALES = {"huber": 1.345, "cauchy": 2.385, "tukey": 4.685}  # per unit residual std: 95% efficiency


def candidates() -> dict[str, dict]:
    """Name -> ``icp`` keywords of every registration the table compares (1 m correspondence distance)."""
    residual_std_m = Ladar().range_std_m
    table = {}
    for method in ("point_to_plane", "gicp"):
        table[method] = {"method": method, "max_correspondence_distance": 1.0}
        for kernel, factor in KERNEL_EFFICIENCY_SCALES.items():
            scale = round(factor * residual_std_m, 3)
            robust = {"robust_kernel": kernel, "kernel_scale": scale}
            table[f"{method} + {kernel} {scale:g} m"] = {**table[method], **robust}
    return table


def candidate_table(seed_sets=SEED_SETS, progress: bool = False) -> dict[str, list[dict]]:
    """Name -> per seed set, the ``recall_summary`` of each candidate registration with all returns."""
    settings = candidates()
    errors = {name: [[] for _ in seed_sets] for name in settings}
    total = sum(len(seeds) for seeds in seed_sets)
    with tqdm(total=total, desc="registration candidates", unit="pair", disable=not progress) as bar:
        for index, seeds in enumerate(seed_sets):
            for seed in seeds:
                pair = terrain_frame_pair(np.random.default_rng(seed))
                for name, keywords in settings.items():
                    errors[name][index].append(PairRegistration(pair, keywords)()["error_after_m"])
                bar.update()
    return {name: [recall_summary(values) for values in per_set] for name, per_set in errors.items()}


def best_candidate(table: dict[str, list[dict]]) -> str:
    """The name with the highest lowest-over-the-sets 5 cm recall, then mean 5 cm recall, then lowest mean median."""

    def key(name: str) -> tuple[float, float, float]:
        recalls = [row["recall_5cm"] for row in table[name]]
        medians = [row["median_error_after_m"] for row in table[name]]
        return min(recalls), float(np.mean(recalls)), -float(np.mean(medians))

    return max(table, key=key)


def registration_recall(seed_sets=SEED_SETS, progress: bool = False) -> dict:
    """Both tables (module docstring) and the registration chosen, as one JSON-ready dict."""
    table = candidate_table(seed_sets, progress)
    control_points = [
        seed_statistics(seeds, progress=progress)["methods"]
        for seeds in tqdm(seed_sets, desc="control-point sets", unit="set", disable=not progress)
    ]
    return {
        "seed_sets": [[seeds[0], seeds[-1]] for seeds in seed_sets],
        "candidates": {name: {"settings": keywords, "sets": table[name]} for name, keywords in candidates().items()},
        "best_by_recall": best_candidate(table),
        "frame_pair_icp": dict(FRAME_PAIR_ICP),
        "control_points": control_points,
    }


def recall_markdown(result: dict) -> str:
    """The two tables as Markdown (recall in %, errors in mm)."""
    sets = [f"{first}-{last}" for first, last in result["seed_sets"]]
    lines = [
        "## Registrations, all returns: recall at 5 cm / 10 cm [%], median [mm] (mean [mm]) per seed set",
        "",
        "| registration | " + " | ".join(sets) + " |",
        "| --- |" + " ---: |" * len(sets),
    ]
    for name, entry in result["candidates"].items():
        lines.append(f"| {name} | " + " | ".join(_cell(row) for row in entry["sets"]) + " |")
    lines += [
        "",
        f"Best by recall: `{result['best_by_recall']}`; frame pairs use `{result['frame_pair_icp']}`.",
        "",
        "## Control points (a quarter of the returns) with that registration, same cells",
        "",
        "| control points | " + " | ".join(sets) + " |",
        "| --- |" + " ---: |" * len(sets),
    ]
    for name in result["control_points"][0]:
        lines.append(f"| {name} | " + " | ".join(_cell(methods[name]) for methods in result["control_points"]) + " |")
    return "\n".join(lines) + "\n"


def _cell(row: dict) -> str:
    return (
        f"{100 * row['recall_5cm']:.0f} / {100 * row['recall_10cm']:.0f}, "
        f"{1e3 * row['median_error_after_m']:.1f} ({1e3 * row['mean_error_after_m']:.1f})"
    )
