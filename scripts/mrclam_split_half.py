"""Held-out check of the noise calibration: fit it on the first half of an MRCLAM dataset, replay the second half.

    python scripts/mrclam_split_half.py ../shared/datasets/MRCLAM_Dataset6

Prints, for the second half (``infonav replay``: every landmark reading, a pose filter per robot): the mean position
RMSE, mean NEES and the share of steps inside the two-sided 95 % band, on the logs the first half's model corrects
and on the raw logs; then the outage ratio (robot 2 without landmarks from 60 s into the half, against dead
reckoning); then ``infonav/MRCLAMLocalization-v0``'s greedy episodes (seeds 0..49) in the second half, on the raw
logs, on the corrected ones, and on the corrected ones with the model's noise in the filter (``calibrated_noise``).
"""

from __future__ import annotations

import argparse
import tempfile
import warnings
from pathlib import Path

import numpy as np

from infonav_gym import make_env
from infonav_gym.datasets import mrclam
from infonav_gym.experiments.replay import ReplayConfig, calibrate, replay
from infonav_gym.experiments.replay.metrics import fraction_inside_95

ENV_EPISODES = 50


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset_dir")
    args = parser.parse_args()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dataset = mrclam.load(args.dataset_dir)
    half = 0.5 * (dataset.end_time - dataset.start_time)
    model, _ = calibrate(dataset.within(0.0, half))
    with tempfile.TemporaryDirectory() as directory:
        fitted = str(model.save(Path(directory) / "first_half.json"))
        for name, noise in (("logs corrected by the first half's model", fitted), ("raw logs", "picked")):
            mean = replay(args.dataset_dir, ReplayConfig(noise=noise, start_s=half))["mean"]
            print(
                f"second half, replay of every landmark, {name}: position RMSE {mean['position_rmse_m']:.3f} m, "
                f"mean NEES {mean['mean_nees']:.2f}, inside 95 % {mean['nees_fraction_inside_95']:.3f}"
            )
        outage = ReplayConfig(noise=fitted, start_s=half, cooperative=True, outage_robot=2, outage_start_s=half + 60)
        print(
            f"second half, outage ratio (robot 2 from 60 s): {replay(args.dataset_dir, outage)['outage']['ratio']:.3f}"
        )
        variants = {
            "raw logs": {},
            "logs corrected by the first half's model": {"log_correction": fitted},
            "logs corrected by the first half's model, its noise": {"log_correction": fitted, "calibrated_noise": True},
        }
        for name, config in variants.items():
            nees, rmse = greedy_episodes(args.dataset_dir, half, **config)
            print(
                f"second half, MRCLAMLocalization-v0 greedy, {name}: mean NEES {nees.mean():.2f}, inside 95 % "
                f"{fraction_inside_95(nees, 3):.3f}, position RMSE {rmse:.3f} m"
            )


def greedy_episodes(dataset_dir: str, from_s: float, **config) -> tuple[np.ndarray, float]:
    """The pose NEES of every step of ``ENV_EPISODES`` greedy episodes of the env (``config``) after ``from_s``, and
    their position RMSE [m]."""
    env = make_env("infonav/MRCLAMLocalization-v0", dataset_dir=dataset_dir, time_from_s=from_s, **config)
    nees, squares = [], []
    for seed in range(ENV_EPISODES):
        _, info = env.reset(seed=seed)
        for _ in range(env.unwrapped.config["horizon"]):
            _, _, _, _, info = env.step(
                int(np.argmax(np.where(info["action_mask"], info["action_information_gain"], -1)))
            )
            nees.append(info["pose_nees"])
            squares.append(info["position_error_m"] ** 2)
    return np.array(nees), float(np.sqrt(np.mean(squares)))


if __name__ == "__main__":
    main()
