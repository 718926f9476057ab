"""Held-out check of the noise calibration: fit it on the first half of an MRCLAM dataset, replay the second half.

    python scripts/mrclam_split_half.py ../shared/datasets/MRCLAM_Dataset6

Prints, for the second half (all landmarks, a pose filter per robot): the mean position RMSE, mean NEES, the
share of time steps inside the 95 % band and the mean NIS, with the model fitted on the first half and
with the hand-picked noise; then the outage ratio (robot 2 without landmarks from 60 s into the half).
"""

from __future__ import annotations

import argparse
import dataclasses
import warnings

from infonav_gym.datasets import mrclam
from infonav_gym.experiments.replay import ReplayConfig, calibrate, replay


def restrict(dataset, start: float, end: float):
    """``dataset`` with only the log rows whose time lies in ``[start, end)`` (absolute times [s])."""

    def cut(tables):
        return {robot: rows[(rows[:, 0] >= start) & (rows[:, 0] < end)] for robot, rows in tables.items()}

    return dataclasses.replace(
        dataset,
        odometry=cut(dataset.odometry),
        landmark_measurements=cut(dataset.landmark_measurements),
        robot_measurements=cut(dataset.robot_measurements),
        groundtruth=cut(dataset.groundtruth),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset_dir")
    args = parser.parse_args()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dataset = mrclam.load(args.dataset_dir)
    middle = 0.5 * (dataset.start_time + dataset.end_time)
    first, second = restrict(dataset, dataset.start_time, middle), restrict(dataset, middle, dataset.end_time + 1.0)
    model, _ = calibrate(first)
    for name, noise in (("fitted on the first half", model), ("hand-picked", None)):
        mean = replay(second, ReplayConfig(noise=noise))["mean"]
        print(
            f"second half, noise {name}: position RMSE {mean['position_rmse_m']:.3f} m, mean NEES "
            f"{mean['mean_nees']:.2f}, inside 95 % {mean['nees_fraction_inside_95']:.3f}, "
            f"mean NIS {mean['mean_nis']:.2f}"
        )
    outage = replay(second, ReplayConfig(noise=model, cooperative=True, outage_robot=2, outage_start_s=60.0))
    print(f"second half, outage ratio (robot 2 from 60 s): {outage['outage']['ratio']:.3f}")


if __name__ == "__main__":
    main()
