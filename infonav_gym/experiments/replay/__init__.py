"""Replay of information-driven measurement selection on logged real robot data (MRCLAM).

``replay(dataset_dir, ReplayConfig(...))`` plays the suite's MRCLAM envs over a dataset's whole log (a pose filter per
robot with the landmark map, or one joint filter over all robots) under a selection policy; ``run_experiments``
sweeps policies and runs the absolute-sensing outage experiment. ``calibrate`` fits a ``NoiseModel`` to a dataset's
ground truth; ``ReplayConfig(noise=...)`` replays the logs it corrects (``"shipped"``: the model fitted on Dataset 6;
a JSON file of ``calibrate``'s; ``"picked"``: the raw logs with the dataset README's stds).
"""

from infonav_gym.datasets.noise_model import NoiseModel, load_noise_model, shipped_noise_model
from infonav_gym.experiments.replay.calibration import calibrate
from infonav_gym.experiments.replay.report import check_experiments, markdown_table, run_experiments, write_results
from infonav_gym.experiments.replay.run import POLICIES, ReplayConfig, replay

__all__ = [
    "POLICIES",
    "NoiseModel",
    "ReplayConfig",
    "calibrate",
    "check_experiments",
    "load_noise_model",
    "markdown_table",
    "replay",
    "run_experiments",
    "shipped_noise_model",
    "write_results",
]
