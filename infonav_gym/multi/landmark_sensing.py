"""Landmark sensing of a team on a ``JointEKF``: which landmarks each robot sees, their models, their updates."""

from __future__ import annotations

import numpy as np

from infonav_gym.estimation.models import range_bearing


class LandmarkSensing:
    """Range-bearing observations of known landmarks by a team's relative-pose sensors; a mixin of a team env.

    The host has ``ekf`` (a ``JointEKF``), ``world`` (its landmarks and line of sight), ``relative_sensors``
    (one ``RelativePoseSensor`` or None per robot: its range-bearing part sees landmarks), ``_true_poses``
    (R, 3), ``possible_agents`` and the generator ``_landmark_rng``.
    """

    def _visible_landmarks(self) -> np.ndarray:
        """Which landmarks each robot's sensor sees from its true pose: range, field of view, line of sight (R, L)."""
        landmarks = self.world.landmarks
        visible = np.zeros((len(self.possible_agents), len(landmarks)), dtype=bool)
        for robot, sensor in enumerate(self.relative_sensors):
            if sensor is None or not len(landmarks):
                continue
            covered = sensor.range_bearing.in_coverage(range_bearing(self._true_poses[robot], landmarks))
            if covered.any():
                visible[robot, covered] = self.world.line_of_sight(self._true_poses[robot, :2], landmarks[covered])
        return visible

    def _landmark_models(self, robots: np.ndarray, landmarks: np.ndarray):
        """``(predicted (M, 2), H_pose (M, 2, 3), R (M, 2, 2))`` of robot ``robots[k]`` observing ``landmarks[k]``."""
        predicted, H_pose = self.ekf.landmark_model(robots, self.world.landmarks[landmarks])
        R = np.empty((len(robots), 2, 2))
        for k, robot in enumerate(robots.tolist()):
            R[k] = self.relative_sensors[robot].range_bearing.noise_covariance(predicted[k, 0])[0]
        return predicted, H_pose, R

    def _observe_landmarks(self, robots: np.ndarray, landmarks: np.ndarray) -> None:
        """Fuse the observations of landmark ``landmarks[k]`` by robot ``robots[k]``, linearized at the estimate."""
        self._observed_landmarks = list(zip(robots.tolist(), landmarks.tolist()))
        if robots.size == 0:
            return
        predicted, H_pose, R = self._landmark_models(robots, landmarks)
        positions = self.world.landmarks[landmarks]
        measurements = np.array(
            [
                self.relative_sensors[robot].range_bearing.measure(
                    self._true_poses[robot], position, self._landmark_rng
                )
                for robot, position in zip(robots.tolist(), positions)
            ]
        ).reshape(-1, 2)
        self.ekf.landmark_update(robots, measurements, predicted, H_pose, R, check_input=False)
