"""The robots' paths of copy 0 of a team vector env and how its robots are drawn (``FirstCopyPaths``)."""

from __future__ import annotations

import numpy as np

from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.scene import PathHistory, RobotDrawing


class FirstCopyPaths:
    """The true and estimated paths of copy 0's robots in a team vector env (what its frames draw)."""

    def __init__(self, true_poses: np.ndarray, estimates: np.ndarray):
        """Start every robot's paths at its true pose and estimate (R, 3)."""
        self.true_paths = [PathHistory(pose[:2]) for pose in true_poses]
        self.estimated_paths = [PathHistory(pose[:2]) for pose in estimates]

    def extend(self, true_poses: np.ndarray, estimates: np.ndarray) -> None:
        """Append every robot's current true and estimated position (R, 3) to its paths."""
        for path, pose in zip(self.true_paths + self.estimated_paths, [*true_poses, *estimates]):
            path.append(pose[:2])  # PathHistory copies

    def drawings(self, true_poses, x, P, agents, gps_available) -> list[RobotDrawing]:
        """Every robot's truth (R, 3), estimate and covariance (from the joint ``x`` (3R,), ``P`` (3R, 3R)) and paths,
        labelled with its name (``agents``) and whether it has a DGPS fix (``gps_available`` (R,))."""
        estimates = x.reshape(-1, POSE_DIM)
        return [
            RobotDrawing(
                true_pose=true_poses[k],
                estimated_pose=estimates[k],
                pose_covariance=P[POSE_DIM * k : POSE_DIM * (k + 1), POSE_DIM * k : POSE_DIM * (k + 1)],
                true_path=self.true_paths[k].points(),
                estimated_path=self.estimated_paths[k].points(),
                label=f"{agent}{'' if available else ', no GPS'}",
            )
            for k, (agent, available) in enumerate(zip(agents, gps_available))
        ]
