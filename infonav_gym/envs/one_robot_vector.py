"""``OneRobotVectorEnv``: the native vector envs of one robot with a range-bearing sensor and odometry.

Their copies' robots move in a ``WorldBatch``; each copy's odometry and measurement noise come from its own
streams (``NoiseStreams``, the single env's two generators drawn ahead), and the EKFs predict from the noisy
odometry on the compiled core, as ``PoseEKF.predict`` does.
"""

from __future__ import annotations

import numpy as np

from infonav_gym.compiled import contiguous, stacked
from infonav_gym.envs.landmark_decision import LandmarkDecision
from infonav_gym.envs.noise_streams import NoiseStreams
from infonav_gym.envs.one_robot import predicted_from_odometry
from infonav_gym.envs.vector_base import InfoNavVectorEnv
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.scene import PathHistory, RobotDrawing
from infonav_gym.sensors.range_bearing import RangeBearingSensor
from infonav_gym.world.scenarios import Scenario
from infonav_gym.world.world_batch import WorldBatch


class OneRobotVectorEnv(InfoNavVectorEnv):
    """Base of ``LandmarkSelectionVectorEnv`` and ``ActiveLocalizationVectorEnv``: a subclass gives its sensors from
    ``_parts()``, sets up its own stacked state in
    ``_allocate()`` and draws its copy 0's robot with ``_first_robot_drawing`` (see ``InfoNavVectorEnv``)."""

    def _build(self) -> None:
        num_envs = self.num_envs
        self._sensor, self._odometry = self._parts()
        self._odometry_covariance = self._odometry.noise_covariance()
        self._odometry_covariances = stacked(self._odometry_covariance, (num_envs, 1, 2, 2))  # what the kernel takes
        self._odometry_stds = float(self._odometry.speed_std_mps), float(self._odometry.turn_rate_std_rps)
        self._measurement_stds = self._sensor.noise_stds  # what the kernels take, made once
        self._worlds = WorldBatch(num_envs)
        self._odometry_noise, self._measurement_noise = NoiseStreams(num_envs, 2), NoiseStreams(num_envs, 2)
        self._true_path = self._estimated_path = None  # copy 0's, when drawing
        self._allocate()

    def _parts(self):
        """Hook: check its own config keys, set its spaces (``_set_spaces``); return its
        ``(RangeBearingSensor, OdometrySensor)``."""
        raise NotImplementedError(f"{type(self).__name__} must implement _parts()")

    def _allocate(self) -> None:
        """Hook: the subclass's stacked arrays of ``num_envs`` copies."""
        raise NotImplementedError(f"{type(self).__name__} must implement _allocate()")

    @property
    def sensor(self) -> RangeBearingSensor:
        """The range-bearing sensor every copy carries (coverage and noise)."""
        return self._sensor

    def estimate(self, copy: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Sub-env ``copy``'s EKF state and covariance now, ``(x (n,), P (n, n))`` (copies)."""
        return self._x[copy].copy(), self._P[copy].copy()

    def scenario(self, copy: int = 0) -> Scenario:
        """The scenario sub-env ``copy`` runs in its current episode (its landmarks, routes, walls)."""
        return self._worlds.scenario(copy)

    def _moved(self, copies: np.ndarray, x: np.ndarray, P: np.ndarray, commands=None):
        """Drive the robots of ``copies`` one step (``commands`` (n, 2) or their routes); their predicted ``(x, P)``
        (``PoseEKF.predict`` from the noisy odometry, on the compiled core)."""
        dt = float(self.config["time_step_s"])
        controls = self._worlds.step(dt, copies, None if commands is None else commands[:, None])
        noise, covariances = self._odometry_noise.reserve(), self._odometry_covariances[: len(copies)]
        x, P = contiguous(x), contiguous(P)
        return predicted_from_odometry(x, P, controls, copies, *noise, self._odometry_stds, dt, covariances)

    def _measured(self, decision: LandmarkDecision, chosen: np.ndarray):
        """Each copy's EKF updated at ``decision`` with a noisy measurement of its chosen landmark (N,), -1: none
        (taken from its true pose now, its noise from its own stream); ``(x, P, realized MI (N,) [nats])``."""
        true_poses = self._worlds.poses[:, 0]
        noise, stds = self._measurement_noise, self._measurement_stds
        return decision.observe(self._x, self._P, chosen, true_poses, self._landmarks, noise, stds)

    def _track_first_copy(self, copies: np.ndarray, stepped: np.ndarray) -> None:
        """When drawing: extend copy 0's true and estimated paths if it is among ``copies`` and stepped, else start
        them anew (it was reset). ``copies`` ascending, ``stepped`` per copy."""
        if self.render_mode is None or copies[0] != 0:
            return
        true_position, estimated_position = self._worlds.poses[0, 0, :2], self._x[0, :2]
        if stepped[0] and self._true_path is not None:
            self._true_path.append(true_position)
            self._estimated_path.append(estimated_position)
        else:
            self._true_path, self._estimated_path = PathHistory(true_position), PathHistory(estimated_position)

    def _first_robot_drawing(self) -> RobotDrawing:
        """Copy 0's robot: its true pose, the EKF's pose and covariance, and both paths."""
        return RobotDrawing(
            true_pose=self._worlds.poses[0, 0].copy(),
            estimated_pose=self._x[0, :POSE_DIM].copy(),
            pose_covariance=self._P[0, :POSE_DIM, :POSE_DIM].copy(),
            true_path=self._true_path.points(),
            estimated_path=self._estimated_path.points(),
        )
