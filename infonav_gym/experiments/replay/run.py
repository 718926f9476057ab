"""One replay of a dataset under a policy, summarized per robot against ground truth."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from infonav_gym.datasets.mrclam import MRCLAMDataset
from infonav_gym.datasets.noise_model import corrected_logs
from infonav_gym.datasets.timeline import LANDMARK, ROBOT, Timeline, make_timeline
from infonav_gym.experiments.replay.filters import ReplayConfig, ReplayTrace, replay_filter
from infonav_gym.experiments.replay.metrics import (
    fraction_inside_95,
    groundtruth_at,
    mean_entropy,
    nees_series,
    nis_summary,
    pose_rmse,
)

NO_GROUNDTRUTH_POSITION_STD_M = 3.0  # [m] initial uncertainty of a robot without ground truth
SUMMARY_KEYS = (
    "position_rmse_m",
    "heading_rmse_rad",
    "mean_nees",
    "nees_fraction_inside_95",
    "dead_reckoning_position_rmse_m",
    "dead_reckoning_heading_rmse_rad",
    "updates_used",
    "relative_updates_used",
    "updates_gated",
    "mean_entropy_nats",
    "mean_nis",
    "nis_inside_95",
)
NEES_PLOT_STEP_S = 1.0  # [s] spacing of the NEES-over-time samples an all-landmark replay keeps


def initial_state(dataset: MRCLAMDataset, config: ReplayConfig) -> tuple[np.ndarray, np.ndarray]:
    """Start poses (N, 3) and covariances (N, 3, 3): ground truth at the first odometry time where known, else the
    landmarks' centroid, heading 0, with a broad covariance."""
    poses, covariances = [], []
    for robot in dataset.robots:
        if robot in dataset.groundtruth:
            pose, _ = groundtruth_at(dataset.groundtruth[robot], np.array([dataset.start_time]))
            poses.append(pose[0])
            stds = [config.initial_position_std_m] * 2 + [config.initial_heading_std_rad]
        else:
            poses.append([*dataset.landmarks.mean(axis=0), 0.0])
            stds = [NO_GROUNDTRUTH_POSITION_STD_M] * 2 + [math.pi]
        covariances.append(np.diag(np.square(stds)))
    return np.array(poses, dtype=float), np.array(covariances)


def replay_header(dataset: MRCLAMDataset, timeline: Timeline, config: ReplayConfig) -> dict:
    """What every replay result starts with: the dataset, the settings and the span replayed."""
    return {
        "dataset": str(dataset.path),
        "config": config.as_dict(),
        "duration_s": timeline.n_ticks * timeline.dt,
        "has_groundtruth": dataset.has_groundtruth,
        "unknown_barcodes": dataset.unknown_barcodes,
    }


def replay(
    dataset: MRCLAMDataset,
    config: ReplayConfig | None = None,
    *,
    dt: float = 0.02,
    duration_s: float | None = None,
    timeline: Timeline | None = None,
    progress: bool = False,
) -> dict:
    """Replay ``dataset`` through the filter ``config`` describes and summarize it.

    Args:
        dataset: a loaded MRCLAM dataset.
        config: filter, policy, budget and outage settings (default: all landmarks, a pose filter per robot).
        dt, duration_s: tick length of the replay clock [s]; replay only this long [s] (None: all).
        timeline: a precomputed ``make_timeline(corrected_logs(dataset, config.noise), dt, duration_s)`` to reuse.
        progress: show a tqdm bar.

    Returns:
        A JSON-ready dict: ``config``, ``robots`` (subject -> metrics), ``mean`` (over robots) and, with an outage,
        ``outage`` (the outage robot's RMSE over the span against a landmark-only replay in which it dead-reckons).
    """
    config = config or ReplayConfig()
    if config.outage_robot is not None and config.outage_robot not in dataset.robots:
        raise ValueError(f"outage robot {config.outage_robot} is not one of the robots {list(dataset.robots)}")
    dataset = corrected_logs(dataset, config.noise)
    timeline = timeline or make_timeline(dataset, dt=dt, duration_s=duration_s)
    poses, covariances = initial_state(dataset, config)
    trace = replay_filter(dataset, timeline, poses, covariances, config, progress=progress)
    robots = _robot_metrics(dataset, timeline, trace, keep_nees=config.policy == "all")
    result = {
        **replay_header(dataset, timeline, config),
        "dt_s": timeline.dt,
        "robots": robots,
        "mean": {},  # over the robots that have each metric
    }
    for key in SUMMARY_KEYS:
        values = [metrics[key] for metrics in robots.values() if metrics[key] is not None]
        result["mean"][key] = float(np.mean(values)) if values else None
    if config.outage_robot is not None:
        baseline_config = dataclasses.replace(config, policy="all", cooperative=False)
        baseline = trace
        if baseline_config != config:
            baseline = replay_filter(dataset, timeline, poses, covariances, baseline_config)
        result["outage"] = _outage_metrics(dataset, timeline, config, trace, baseline)
    return result


def _robot_metrics(dataset: MRCLAMDataset, timeline: Timeline, trace: ReplayTrace, keep_nees: bool) -> dict:
    """Per robot: updates, entropy, NIS and, against ground truth, RMSE and NEES (its series if ``keep_nees``)."""
    times = timeline.start_time + timeline.boundary_times()
    robots = {}
    for index, robot in enumerate(dataset.robots):
        kinds = np.asarray(trace.kinds[index], dtype=int)
        accepted = np.asarray(trace.accepted[index], dtype=bool)
        metrics = {
            "updates_used": int(np.sum(accepted & (kinds == LANDMARK))),
            "relative_updates_used": int(np.sum(accepted & (kinds == ROBOT))),
            "updates_gated": int(np.sum(~accepted)),
            "mean_entropy_nats": mean_entropy(trace.covariances[:, index]),
            **nis_summary(trace.nis[index], trace.accepted[index]),
            "choices": trace.choices[index],
        }
        metrics.update(dict.fromkeys(SUMMARY_KEYS[:6]))
        metrics["evaluated_s"] = 0.0
        if robot in dataset.groundtruth:
            truth, valid = groundtruth_at(dataset.groundtruth[robot], times)
            if valid.any():
                estimates = trace.poses[valid, index]
                position, heading = pose_rmse(truth[valid], estimates)
                nees = nees_series(truth[valid], estimates, trace.covariances[valid, index])
                dr_position, dr_heading = pose_rmse(truth[valid], trace.dead_reckoning[valid, index])
                metrics.update(
                    position_rmse_m=position,
                    heading_rmse_rad=heading,
                    mean_nees=float(nees.mean()),
                    nees_fraction_inside_95=fraction_inside_95(nees, 3),
                    dead_reckoning_position_rmse_m=dr_position,
                    dead_reckoning_heading_rmse_rad=dr_heading,
                    evaluated_s=float(valid.sum() * timeline.dt),
                )
                if keep_nees:
                    step = max(1, round(NEES_PLOT_STEP_S / timeline.dt))
                    metrics["nees_over_time"] = {
                        "time_s": timeline.boundary_times()[valid][::step].tolist(),
                        "nees": nees[::step].tolist(),
                    }
        robots[str(robot)] = metrics
    return robots


def _outage_metrics(dataset, timeline, config, trace, baseline) -> dict:
    index = dataset.robots.index(config.outage_robot)
    boundary_times = timeline.boundary_times()
    span = (boundary_times >= config.outage_start_s) & (boundary_times < config.outage_end_s)
    outage = {
        "robot": config.outage_robot,
        "start_s": config.outage_start_s,
        "end_s": float(min(config.outage_end_s, boundary_times[-1])),
        "position_rmse_m": None,
        "without_relative_position_rmse_m": None,
        "dead_reckoning_from_start_position_rmse_m": None,
        "ratio": None,
    }
    if config.outage_robot not in dataset.groundtruth:
        warnings.warn(f"robot {config.outage_robot} has no ground truth: no outage RMSE", stacklevel=3)
        return outage
    truth, valid = groundtruth_at(dataset.groundtruth[config.outage_robot], timeline.start_time + boundary_times)
    mask = span & valid
    if not mask.any():
        return outage
    position, _ = pose_rmse(truth[mask], trace.poses[mask, index])
    without, _ = pose_rmse(truth[mask], baseline.poses[mask, index])
    dead_reckoning, _ = pose_rmse(truth[mask], trace.dead_reckoning[mask, index])
    outage.update(
        position_rmse_m=position,
        without_relative_position_rmse_m=without,
        dead_reckoning_from_start_position_rmse_m=dead_reckoning,
        ratio=position / without,
        evaluated_s=float(mask.sum() * timeline.dt),
    )
    return outage
