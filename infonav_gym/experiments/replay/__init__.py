"""Replay of information-driven measurement selection on logged real robot data (MRCLAM).

``replay(dataset, ReplayConfig(...))`` runs the batched EKF (a pose filter per robot with the landmark
map, or one joint filter over all robots) through a dataset's odometry and measurements in time order,
with chi-square innovation gating, under a selection policy; ``run_experiments`` sweeps
policies and budgets and runs the absolute-sensing outage experiment. ``calibrate`` fits a
``NoiseModel`` to a dataset's ground truth; ``ReplayConfig(noise=...)`` replays with it
(``shipped_noise_model()``: the one fitted on Dataset 6; ``noise=None``: the hand-picked stds).
"""

from infonav_gym.datasets.noise_model import NoiseModel, load_noise_model, shipped_noise_model
from infonav_gym.datasets.timeline import make_timeline
from infonav_gym.experiments.replay.calibration import calibrate
from infonav_gym.experiments.replay.filters import ReplayConfig
from infonav_gym.experiments.replay.policies import POLICIES
from infonav_gym.experiments.replay.report import check_experiments, markdown_table, run_experiments, write_results
from infonav_gym.experiments.replay.run import replay

__all__ = [
    "POLICIES",
    "NoiseModel",
    "ReplayConfig",
    "calibrate",
    "check_experiments",
    "load_noise_model",
    "make_timeline",
    "markdown_table",
    "replay",
    "run_experiments",
    "shipped_noise_model",
    "write_results",
]
