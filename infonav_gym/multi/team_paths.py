"""The robots' paths of a team env and how its robots are drawn (``TeamPaths``)."""

from __future__ import annotations

import numpy as np

from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.scene import PathHistory, RobotDrawing


class TeamPaths:
    """The true and estimated paths of a team env's robots, and their drawings; a mixin (of a team env still
    written twice: one written once keeps its copy 0's in a ``FirstCopyPaths``).

    The host has ``ekf`` (a ``JointEKF``), ``_true_poses`` (R, 3), ``_gps_available`` (R,) and ``possible_agents``.
    """

    def _start_paths(self) -> None:
        """Start every robot's true and estimated path at its current pose."""
        self._true_paths = [PathHistory(pose[:2]) for pose in self._true_poses]
        self._estimated_paths = [PathHistory(pose[:2]) for pose in self.ekf.poses]

    def _extend_paths(self) -> None:
        """Append every robot's current true and estimated position to its paths."""
        for robot, (true_pose, estimate) in enumerate(zip(self._true_poses, self.ekf.x.reshape(-1, POSE_DIM))):
            self._true_paths[robot].append(true_pose[:2])
            self._estimated_paths[robot].append(estimate[:2])  # PathHistory copies

    def _robot_drawings(self) -> list[RobotDrawing]:
        """Every robot's truth, estimate, covariance and paths, labelled with its name and whether it has DGPS."""
        estimates = self.ekf.poses
        return [
            RobotDrawing(
                true_pose=self._true_poses[k],
                estimated_pose=estimates[k],
                pose_covariance=self.ekf.pose_covariance(k),
                true_path=self._true_paths[k].points(),
                estimated_path=self._estimated_paths[k].points(),
                label=f"{self.possible_agents[k]}{'' if self._gps_available[k] else ', no GPS'}",
            )
            for k in range(len(self.possible_agents))
        ]


class FirstCopyPaths:
    """The true and estimated paths of copy 0's robots in a team vector env (what its frames draw)."""

    def __init__(self, true_poses: np.ndarray, estimates: np.ndarray):
        """Start every robot's paths at its true pose and estimate (R, 3)."""
        self.true_paths = [PathHistory(pose[:2]) for pose in true_poses]
        self.estimated_paths = [PathHistory(pose[:2]) for pose in estimates]

    def extend(self, true_poses: np.ndarray, estimates: np.ndarray) -> None:
        """Append every robot's current true and estimated position (R, 3) to its paths."""
        for robot, (true_pose, estimate) in enumerate(zip(true_poses, estimates)):
            self.true_paths[robot].append(true_pose[:2])
            self.estimated_paths[robot].append(estimate[:2])  # PathHistory copies

    def drawings(self, true_poses, x, P, labels) -> list[RobotDrawing]:
        """Every robot's truth (R, 3), estimate and covariance (from the joint ``x`` (3R,), ``P`` (3R, 3R)), paths and
        label."""
        estimates = x.reshape(-1, POSE_DIM)
        return [
            RobotDrawing(
                true_pose=true_poses[k],
                estimated_pose=estimates[k],
                pose_covariance=P[POSE_DIM * k : POSE_DIM * (k + 1), POSE_DIM * k : POSE_DIM * (k + 1)],
                true_path=self.true_paths[k].points(),
                estimated_path=self.estimated_paths[k].points(),
                label=label,
            )
            for k, label in enumerate(labels)
        ]
