"""Replay of information-driven measurement selection on logged real robot data (MRCLAM).

``replay(dataset, ReplayConfig(...))`` runs one filter (PoseEKF per robot with the landmark
map, or a cooperative JointEKF) through a dataset's odometry and measurements in time order,
with chi-square innovation gating, under a selection policy; ``run_experiments`` sweeps
policies and budgets and runs the absolute-sensing outage experiment.
"""

from infonav_gym.experiments.replay.filters import ReplayConfig
from infonav_gym.experiments.replay.policies import POLICIES
from infonav_gym.experiments.replay.report import check_experiments, markdown_table, run_experiments, write_results
from infonav_gym.experiments.replay.run import replay
from infonav_gym.experiments.replay.timeline import make_timeline

__all__ = [
    "POLICIES",
    "ReplayConfig",
    "check_experiments",
    "make_timeline",
    "markdown_table",
    "replay",
    "run_experiments",
    "write_results",
]
