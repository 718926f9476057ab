"""The paper's Fig. 6: two consecutive 3D LADAR frames of a vehicle pitching and rolling over rugged terrain
(``terrain_frame_pair``), before (odometry) and after ICP; the seed statistics report ``registration_error`` recall,
median and mean with all returns and each control-point strategy's quarter."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree
from tqdm.auto import tqdm

from infonav_gym.geometry import transform_error, transform_points
from infonav_gym.registration import icp
from infonav_gym.registration.control_points import select_control_points
from infonav_gym.registration.frame_pairs import FRAME_PAIR_ICP, FramePair, registration_error, terrain_frame_pair
from infonav_gym.registration.gicp import gicp_covariances
from infonav_gym.registration.icp import estimate_normals
from infonav_gym.rendering import matplotlib_figure, save_figure
from infonav_gym.sensors.ladar import sensor_points

SEEDS_COUNT = "how many frame pairs the statistics register"  # what ``n_seeds`` counts, for its error
CONTROL_FRACTION = 0.25  # control points as a fraction of the returns
MIN_CONTROL_POINTS = 3  # the fewest control points a registration is given, whatever the fraction
STRATEGIES = ("entropy", "uniform", "random")
RECALL_THRESHOLDS_M = (0.05, 0.10)  # a pair is registered when its registration error is below the threshold


class PairRegistration:
    """ICP of a pair's newer frame (all returns or control points) onto the older, with ``settings`` (``icp`` keywords);
    GICP's frame covariances are computed once per pair."""

    def __init__(self, pair: FramePair, settings: dict = FRAME_PAIR_ICP):
        self.pair, self.settings = pair, settings
        self.source, self.target = sensor_points(pair.current), sensor_points(pair.previous)
        self._covariances = None

    def __call__(self, control_points=None) -> dict:
        """Errors before and after ICP of the ``control_points`` rows of the newer frame (default all)."""
        rows = slice(None) if control_points is None else control_points
        pair, covariances = self.pair, {}
        if self.settings.get("method") == "gicp":
            source_covariances, target_covariances = self.frame_covariances()
            covariances = {"source_covariances": source_covariances[rows], "target_covariances": target_covariances}
        result = icp(self.source[rows], self.target, pair.odometry_motion, **self.settings, **covariances)
        translation, rotation = transform_error(result.transform, pair.true_motion)
        return {
            "points": len(self.source[rows]),
            "error_before_m": registration_error(pair.odometry_motion, pair.true_motion),
            "error_after_m": registration_error(result.transform, pair.true_motion),
            "translation_error_m": translation,
            "rotation_error_deg": math.degrees(rotation),
            "iterations": result.iterations,
            "converged": result.converged,
            "transform": result.transform,
        }

    def frame_covariances(self) -> tuple[np.ndarray, np.ndarray]:
        """GICP's covariances of the newer and the older frame's returns, computed on first use and kept."""
        if self._covariances is None:
            self._covariances = gicp_covariances(self.source), gicp_covariances(self.target)
        return self._covariances


def control_point_count(fraction: float, returns: int) -> int:
    """Control points for ``fraction`` of a frame's ``returns``: rounded, at least ``MIN_CONTROL_POINTS``."""
    return max(MIN_CONTROL_POINTS, round(fraction * returns))


def recall_summary(errors_m) -> dict:
    """Recall at each of ``RECALL_THRESHOLDS_M``, median and mean of registration errors [m], and the errors."""
    errors_m = np.asarray(errors_m, dtype=float)
    return {
        **{f"recall_{round(100 * limit)}cm": float(np.mean(errors_m < limit)) for limit in RECALL_THRESHOLDS_M},
        "median_error_after_m": float(np.median(errors_m)),
        "mean_error_after_m": float(errors_m.mean()),
        "errors_after_m": errors_m.tolist(),
    }


def seed_statistics(seeds, progress: bool = False, settings: dict = FRAME_PAIR_ICP) -> dict:
    """Register each seed's pair with all returns and with each strategy's quarter; recall, median, mean per method."""
    records = {name: [] for name in ("all", *STRATEGIES)}
    for seed in tqdm(seeds, desc="Fig. 6 frame pairs", unit="pair", disable=not progress):
        rng = np.random.default_rng(seed)
        pair = terrain_frame_pair(rng)
        registration = PairRegistration(pair, settings)
        records["all"].append(registration())
        k = control_point_count(CONTROL_FRACTION, len(registration.source))
        for strategy in STRATEGIES:
            chosen = select_control_points(
                pair.current, k, strategy, pose_covariance=pair.motion_covariance, np_random=rng
            )
            records[strategy].append(registration(chosen))
    summary = {}
    for name, runs in records.items():
        before = np.array([run["error_before_m"] for run in runs])
        after = np.array([run["error_after_m"] for run in runs])
        summary[name] = {
            "mean_points": float(np.mean([run["points"] for run in runs])),
            "mean_error_before_m": float(before.mean()),
            **recall_summary(after),
            "fraction_improved": float(np.mean(after < before)),
            "mean_translation_error_m": float(np.mean([run["translation_error_m"] for run in runs])),
            "mean_rotation_error_deg": float(np.mean([run["rotation_error_deg"] for run in runs])),
        }
    return {"seeds": list(seeds), "control_fraction": CONTROL_FRACTION, "methods": summary}


def figures(seed: int, seeds, progress: bool) -> tuple[dict, Callable[[Path], object]]:
    """Fig. 6's frame pair of ``seed`` and the statistics over ``seeds`` (JSON-ready), and the function drawing them."""
    pair = terrain_frame_pair(np.random.default_rng(seed))
    registration = PairRegistration(pair)()
    result = {
        "icp": dict(FRAME_PAIR_ICP),
        "fig6": {
            "seed": seed,
            "attitude_deg": {
                "previous": [math.degrees(a) for a in pair.previous.attitude_rad],
                "current": [math.degrees(a) for a in pair.current.attitude_rad],
            },
            "registration": {key: value for key, value in registration.items() if key != "transform"},
            "true_motion": pair.true_motion.tolist(),
            "odometry_motion": pair.odometry_motion.tolist(),
            "icp_motion": registration["transform"].tolist(),
        },
        "seed_statistics": seed_statistics(seeds, progress=progress),
    }
    return result, lambda path: plot_fig6(pair, registration["transform"], registration, path)


def table(result: dict) -> str:
    """The Fig. 6 figures as text: the plotted pair's errors and, over the seeds, mean and median errors and recall."""
    fig6, statistics = result["fig6"], result["seed_statistics"]
    plotted = fig6["registration"]
    seeds = statistics["seeds"]
    lines = [
        f"Fig. 6, seed {fig6['seed']}: registration error {plotted['error_before_m']:.3f} m (odometry) -> "
        f"{plotted['error_after_m']:.3f} m (ICP, {plotted['points']} points, {plotted['iterations']} iterations)",
        f"Frame pairs, seeds {seeds[0]}..{seeds[-1]} (errors in m; rotation error counted at 10 m):",
        f"  {'control points':16s}{'points':>8s}{'before':>9s}{'after':>9s}{'median':>9s}{'<5 cm':>8s}{'<10 cm':>8s}",
    ]
    for name, summary in statistics["methods"].items():
        lines.append(
            f"  {name:16s}{summary['mean_points']:8.0f}{summary['mean_error_before_m']:9.3f}"
            f"{summary['mean_error_after_m']:9.3f}{summary['median_error_after_m']:9.4f}"
            f"{summary['recall_5cm']:8.0%}{summary['recall_10cm']:8.0%}"
        )
    return "\n".join(lines)


_VIEWS = (("top view", 0, 1, "x [m]", "y [m]"), ("side view", 0, 2, "x [m]", "z [m]"))
_POINT_SIZE = 1.5
_RESIDUAL_SCALE_M = 0.2  # colour scale of the residuals [m]


def plot_fig6(pair: FramePair, icp_motion: np.ndarray, registration: dict, path: Path) -> Path:
    """Write ``figure_fig6(pair, icp_motion, registration)`` to ``path``."""
    return save_figure(figure_fig6(pair, icp_motion, registration), path, dpi=120)


def figure_fig6(pair: FramePair, icp_motion: np.ndarray, registration: dict):
    """Fig. 6: rows = top and side views, columns = before (odometry) and after (ICP) registration; the older frame in
    gray, the newer coloured by its point-to-plane residual to the older (misregistration shows warm)."""
    target, source = sensor_points(pair.previous), sensor_points(pair.current)
    tree = cKDTree(target)
    normals = estimate_normals(target, tree)
    placements = (
        ("(a) before: odometry estimate", pair.odometry_motion, registration["error_before_m"]),
        ("(b) after: ICP registration", icp_motion, registration["error_after_m"]),
    )
    figure = matplotlib_figure("plotting Fig. 6", figsize=(13, 8), constrained_layout=True)
    axes = figure.subplots(2, 2)
    dots = {"s": _POINT_SIZE, "lw": 0}
    residual_dots = dots | {"cmap": "turbo", "vmin": 0.0, "vmax": _RESIDUAL_SCALE_M}
    for column, (title, motion, error) in enumerate(placements):
        placed = transform_points(motion, source)
        closest = tree.query(placed)[1]
        residual = np.abs(np.einsum("ij,ij->i", placed - target[closest], normals[closest]))
        for row, (view, first, second, first_label, second_label) in enumerate(_VIEWS):
            ax = axes[row, column]
            ax.scatter(target[:, first], target[:, second], c="0.75", label="older frame (newer: coloured)", **dots)
            points = ax.scatter(placed[:, first], placed[:, second], c=residual, **residual_dots)
            ax.set_title(f"{title}, {view}: error {error:.3f} m", fontsize="medium")
            ax.set(xlabel=first_label, ylabel=second_label)
            if row == 0:
                ax.set_aspect("equal", adjustable="datalim")
            ax.legend(loc="upper right", markerscale=6, fontsize="small")
    figure.colorbar(points, ax=axes, shrink=0.6, label="newer point to the older frame's surface [m]")
    figure.suptitle(
        "Fig. 6: consecutive 3D LADAR frames (32 x 180) of a vehicle pitching and rolling over rugged terrain, "
        f"before and after ICP ({registration['points']} points, {registration['iterations']} iterations)"
    )
    return figure
