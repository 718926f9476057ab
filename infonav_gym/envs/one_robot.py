"""What the one-robot scenarios share (``LandmarkSelection-v0``, ``ActiveLocalization-v0``): a robot with a
range-bearing sensor and odometry, its state, the steps of its EKF and the accessors of its driver."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from infonav_gym.compiled import contiguous, kernel, stacked
from infonav_gym.envs.driver import Driver
from infonav_gym.envs.landmark_decision import LandmarkDecision
from infonav_gym.envs.noise_streams import NoiseStreams, taken
from infonav_gym.envs.observation_kernels import POSE_HIGH, POSE_LOW
from infonav_gym.envs.protocol import EnvScenario, State
from infonav_gym.estimation.kernels import predict_poses
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.scene import PathHistory, RobotDrawing, extended_paths
from infonav_gym.world.world_batch import WorldBatch


@dataclass
class OneRobotState(State):
    """Every copy's world, noise streams, EKF ``x`` (N, n) and ``P`` (N, n, n), landmarks (N, K, 2), which exist
    (N, K), the last action (N,) (-1: none) and copy 0's true and estimated paths (when drawing)."""

    worlds: WorldBatch
    odometry_noise: NoiseStreams
    measurement_noise: NoiseStreams
    x: np.ndarray | None
    P: np.ndarray | None
    landmarks: np.ndarray
    exists: np.ndarray
    chosen: np.ndarray
    geometry: object = None
    paths: tuple[PathHistory, PathHistory] | None = None


class OneRobotScenario(EnvScenario):
    """A scenario of one robot with a ``RangeBearingSensor`` and odometry: its constants and shared steps."""

    def use_sensors(self, sensor, odometry) -> None:
        """Keep the robot's range-bearing ``sensor`` and ``odometry`` and what the kernels take of them."""
        self.sensor, self.odometry = sensor, odometry
        self.odometry_covariance = odometry.noise_covariance()
        self.odometry_covariances = stacked(self.odometry_covariance, (self.copies, 1, 2, 2))
        self.odometry_stds = float(odometry.speed_std_mps), float(odometry.turn_rate_std_rps)
        self.measurement_stds = sensor.noise_stds

    def use_observation_bounds(self, low: list, high: list) -> None:
        """The observation space: the ``pose_features``, then features within ``low``, ``high``; ``bounds``, its
        float32 bounds as floats, for the kernels that clip to them."""
        low, high = np.array(POSE_LOW + low, dtype=np.float32), np.array(POSE_HIGH + high, dtype=np.float32)
        self.bounds = low.astype(float), high.astype(float)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)

    def robot_fields(self, copies: int, n_candidates: int) -> dict:
        """The ``OneRobotState`` fields of ``copies`` copies before their first episode."""
        return {
            "elapsed": np.zeros(copies, dtype=int),
            "worlds": WorldBatch(copies),
            "odometry_noise": NoiseStreams(copies, 2),
            "measurement_noise": NoiseStreams(copies, 2),
            "x": None,
            "P": None,
            "landmarks": np.zeros((copies, n_candidates, 2)),
            "exists": np.zeros((copies, n_candidates), dtype=bool),
            "chosen": np.full(copies, -1),
        }

    def moved(self, state: OneRobotState, copies: np.ndarray, x: np.ndarray, P: np.ndarray, commands=None):
        """Drive the robots of ``copies`` one step (``commands`` (n, 2) or their routes); their predicted ``(x, P)``
        (``PoseEKF.predict`` from the noisy odometry, on the compiled core)."""
        dt = float(self.config["time_step_s"])
        controls = state.worlds.step(dt, copies, None if commands is None else commands[:, None])
        noise, covariances = state.odometry_noise.reserve(), self.odometry_covariances[: len(copies)]
        x, P = contiguous(x), contiguous(P)
        return predicted_from_odometry(x, P, controls, copies, *noise, self.odometry_stds, dt, covariances)

    def measured(self, state: OneRobotState, decision, chosen: np.ndarray):
        """Each copy's EKF updated at ``decision`` (a ``LandmarkDecision`` or a named tuple with its fields) with a
        noisy measurement of its chosen landmark (N,), -1: none (taken from its true pose now, its noise from its own
        stream); ``(x, P, realized MI (N,) [nats])``."""
        arguments = (state.x, state.P, chosen, state.worlds.poses[:, 0], state.landmarks, state.measurement_noise)
        return LandmarkDecision.observe(decision, *arguments, self.measurement_stds, self.threads)

    def follow_first_copy(self, state: OneRobotState, restarted: bool) -> None:
        """When drawing: start copy 0's true and estimated paths anew (``restarted``) or extend them."""
        if not self.drawing:
            return
        state.paths = extended_paths(state.paths, (state.worlds.poses[0, 0, :2], state.x[0, :2]), restarted)

    @staticmethod
    def first_robot_drawing(state: OneRobotState) -> RobotDrawing:
        """Copy 0's robot: its true pose, the EKF's pose and covariance, and both paths."""
        return RobotDrawing(
            true_pose=state.worlds.poses[0, 0].copy(),
            estimated_pose=state.x[0, :POSE_DIM].copy(),
            pose_covariance=state.P[0, :POSE_DIM, :POSE_DIM].copy(),
            true_path=state.paths[0].points(),
            estimated_path=state.paths[1].points(),
        )


class OneRobotDriver(Driver):
    """The driver of a one-robot scenario, with what agents and tests read of its copies."""

    @property
    def sensor(self):
        """The range-bearing sensor every copy carries (coverage and noise)."""
        return self.env_scenario.sensor

    def estimate(self, copy: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Sub-env ``copy``'s EKF state and covariance now, ``(x (n,), P (n, n))`` (copies)."""
        return self.state.x[copy].copy(), self.state.P[copy].copy()

    def scenario(self, copy: int = 0):
        """The scenario sub-env ``copy`` runs in its current episode (its landmarks, routes, walls)."""
        return self.state.worlds.scenario(copy)


@kernel
def predicted_from_odometry(x, P, controls, copies, blocks, next_draw, odometry_stds, dt, covariances):
    """``predict_poses`` of ``copies`` from their robots' odometry readings: the executed ``controls`` (n, 1, 2) plus
    each copy's next draw of ``blocks`` (``NoiseStreams.reserve``'s) times ``odometry_stds``, as
    ``OdometrySensor.measure_with_noise`` reads them."""
    readings = np.empty(controls.shape)
    for row in range(len(copies)):
        noise = taken(blocks, next_draw, copies[row])
        for i in range(2):
            readings[row, 0, i] = controls[row, 0, i] + noise[i] * odometry_stds[i]
    return predict_poses(x, P, readings, dt, covariances)
