"""The planning model of ``infonav/ActiveLocalization-v0``: its transition, batched over hypothetical futures.

``PlannerAgent`` searches action sequences on it. Under the EKF's linearization the posterior
covariance does not depend on the measured values, so a sequence's expected reward is computed
without sampling: ``belief()`` copies the estimator's state, ``plan_decision`` gives the action
masks and gains at each belief, ``plan_step`` predicts one step of each belief under its action.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from infonav_gym.estimation import batched
from infonav_gym.estimation.ekf import POSE_DIM
from infonav_gym.estimation.models import range_bearing_linearized
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import expected_information_gain

# Motion primitives: the heading to steer for, relative to the estimated bearing of the goal [rad].
PRIMITIVE_OFFSETS_RAD = (0.0, math.pi / 4, -math.pi / 4, math.pi / 2, -math.pi / 2)
PRIMITIVE_NAMES = ("to_goal", "veer_left", "veer_right", "sidestep_left", "sidestep_right")
N_PRIMITIVES = len(PRIMITIVE_OFFSETS_RAD)


class BeliefBatch:
    """The batch behaviour of a planning model's belief: a frozen dataclass of arrays, each of leading size B."""

    def __len__(self) -> int:
        return len(getattr(self, next(iter(self.__dataclass_fields__))))

    def take(self, indices):
        """The beliefs at ``indices`` (a new batch, e.g. repeated once per action to try)."""
        return type(self)(*(np.take(getattr(self, name), indices, axis=0) for name in self.__dataclass_fields__))


@dataclass(frozen=True)
class Belief(BeliefBatch):
    """A light copy of the estimator's state at a decision, batched over ``B`` hypothetical futures.

    Attributes:
        pose: estimated poses ``[x, y, heading]`` (B, 3) [m, m, rad].
        covariance: their covariances (B, 3, 3).
        observations_left: remaining sensing budget (B,).
        visible: which landmarks can be observed from there (B, K).
        done: whether the episode has ended (goal reached or uncertainty bound crossed) (B,).
    """

    pose: np.ndarray
    covariance: np.ndarray
    observations_left: np.ndarray
    visible: np.ndarray
    done: np.ndarray


class ActivePlanningModel:
    """The planning model of ``ActiveLocalizationEnv``, a mixin of it (it reads the env's config, world,
    sensor, goal, odometry noise, obstacles, ``_commands`` and ``position_std``).

    What a look-ahead agent uses: ``belief()``, ``plan_decision(belief)``, ``plan_step(belief, actions)``,
    ``position_std(covariances)``, ``n_primitives``, ``max_position_std_m`` and ``idle_primitive``.
    """

    idle_primitive = None  # no primitive stands still: every one drives

    def planning_model(self) -> ActivePlanningModel:
        """The env's planning model (the env itself, through the methods above), for ``PlannerAgent``.

        Reachable through Gymnasium wrappers: ``env.get_wrapper_attr("planning_model")()``.
        """
        return self

    @property
    def max_position_std_m(self) -> float:
        """The failure bound on the largest position standard deviation [m] (config ``max_position_std_m``)."""
        return self.config["max_position_std_m"]

    def belief(self) -> Belief:
        """The estimator's state at the current decision as a batch of one (visibility: from the true pose)."""
        if self._elapsed_steps is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before belief()")
        return Belief(
            pose=self.ekf.x[None].copy(),
            covariance=self.ekf.P[None].copy(),
            observations_left=np.array([self.observations_left]),
            visible=self._visible[None].copy(),
            done=np.array([self.goal_reached or self.failed]),
        )

    def plan_decision(self, belief: Belief) -> tuple[np.ndarray, np.ndarray]:
        """``(action_mask (B, n), action_information_gain (B, n))`` at each belief, as ``info`` would give them.

        Finished beliefs have only no-observation actions valid, all with gain 0.
        """
        B = len(belief)
        H, R = self._model_jacobians(belief.pose)
        gains = np.zeros((B, self.n_slots, N_PRIMITIVES))
        observable = belief.visible & ((belief.observations_left > 0) & ~belief.done)[:, None]
        rows, landmarks = np.nonzero(observable)
        if rows.size:
            gains[rows, 1 + landmarks] = expected_information_gain(
                belief.covariance[rows], H[rows, landmarks], R[rows, landmarks], check_input=False
            )[:, None]
        mask = np.zeros((B, self.n_slots, N_PRIMITIVES), dtype=np.int8)
        mask[:, 0] = 1
        mask[:, 1:] = observable[:, :, None]
        return mask.reshape(B, -1), gains.reshape(B, -1)

    def plan_step(self, belief: Belief, actions) -> tuple[Belief, np.ndarray]:
        """Predict one step of each belief under its action: ``(next beliefs, expected rewards (B,))``.

        The model the env's own transition follows, with the unknowns replaced by their
        expectation: the observation's MI is exact (it does not depend on the measured
        value), the motion is the primitive's command from the estimated pose without
        collisions or noise, progress and the goal are judged from the estimated
        position, and visibility after the move from the predicted pose (range, field of
        view and the round obstacles). An invalid action is the env's no-op; a finished
        belief stays put and earns 0.
        """
        cfg = self.config
        actions = np.asarray(actions, dtype=int)
        slots, primitives = np.divmod(actions, N_PRIMITIVES)
        done = belief.done
        observe = (slots > 0) & ~done & (belief.observations_left > 0)
        landmark = np.maximum(slots - 1, 0)
        observe &= belief.visible[np.arange(len(belief)), landmark]
        valid = ((slots == 0) | observe) & ~done
        covariance = belief.covariance.copy()
        rewards = np.zeros(len(belief))
        rows = np.flatnonzero(observe)
        if rows.size:  # the expected update: the measurement as predicted (a zero residual)
            H, R = self._model_jacobians(belief.pose[rows], landmark[rows])
            gains = batched.landmark_information_gains(covariance[rows], H[:, None], R[:, None], check_input=False)
            rewards[rows] += gains[:, 0] - cfg["observation_cost_nats"]
            no_residual = np.zeros((rows.size, 2))
            covariance[rows] = batched.range_bearing_update(
                belief.pose[rows], covariance[rows], no_residual, no_residual, H, R, check_input=False
            )[1]
        dt = cfg["time_step_s"]
        commands = np.where(valid[:, None], self._commands(belief.pose, primitives), 0.0)
        pose, predicted = batched.predict_pose(
            belief.pose, covariance, commands, dt, self._odometry_covariance, check_input=False
        )
        covariance = np.where(done[:, None, None], covariance, predicted)
        pose = np.where(done[:, None], belief.pose, pose)
        distance_before = np.linalg.norm(belief.pose[:, :2] - self.goal, axis=1)
        distance_after = np.linalg.norm(pose[:, :2] - self.goal, axis=1)
        rewards += np.where(valid, cfg["progress_reward_per_m"] * (distance_before - distance_after), 0.0)
        rewards -= np.where(valid, cfg["motion_cost_per_step"], 0.0)
        reached = ~done & (distance_after <= cfg["goal_radius_m"])
        failed = ~done & ~reached & (self.position_std(covariance) > cfg["max_position_std_m"])
        rewards += cfg["goal_bonus"] * reached - cfg["failure_penalty"] * failed
        following = Belief(
            pose=pose,
            covariance=covariance,
            observations_left=belief.observations_left - observe,
            visible=self._model_visibility(pose),
            done=done | reached | failed,
        )
        return following, rewards

    def _model_jacobians(self, poses: np.ndarray, landmarks=None) -> tuple[np.ndarray, np.ndarray]:
        """Range-bearing Jacobians and noise at each pose: for every landmark (B, K, 2, ...) or one each (B, 2, ...)."""
        positions = self.world.landmarks if landmarks is None else self.world.landmarks[landmarks]
        per_pose = 1 if landmarks is not None else len(positions)
        sensors = np.repeat(poses, per_pose, axis=0)
        targets = positions if landmarks is not None else np.tile(positions, (len(poses), 1))
        predicted, H, _ = range_bearing_linearized(sensors.T, targets)
        R = self.sensor.noise_covariance(predicted[:, 0])
        if landmarks is not None:
            return H, R
        return H.reshape(len(poses), per_pose, 2, POSE_DIM), R.reshape(len(poses), per_pose, 2, 2)

    def _model_visibility(self, poses: np.ndarray) -> np.ndarray:
        """Which landmarks each pose (B, 3) sees: in range and field of view, no round obstacle in the way (B, K)."""
        landmarks = self.world.landmarks
        offsets = landmarks[None] - poses[:, None, :2]  # (B, K, 2)
        ranges = np.hypot(offsets[..., 0], offsets[..., 1])
        bearings = wrap_angle(np.arctan2(offsets[..., 1], offsets[..., 0]) - poses[:, 2:3])
        visible = (ranges <= self.sensor.max_range_m) & (np.abs(bearings) <= 0.5 * self.sensor.fov_rad)
        if len(self._obstacle_radii):
            to_center = self._obstacle_centers[None, None] - poses[:, None, None, :2]  # (B, 1, O, 2)
            length_sq = np.maximum(ranges**2, 1e-12)[..., None]
            along = np.clip(np.einsum("bkoi,bki->bko", to_center, offsets) / length_sq, 0.0, 1.0)
            closest = along[..., None] * offsets[:, :, None, :] - to_center
            blocked = np.einsum("bkoi,bkoi->bko", closest, closest) <= self._obstacle_radii**2
            visible &= ~blocked.any(axis=2)
        return visible
