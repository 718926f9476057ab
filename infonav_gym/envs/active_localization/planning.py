"""The planning model of ``infonav/ActiveLocalization-v0``: its transition, batched over hypothetical futures.

Under the EKF's linearization the posterior covariance does not depend on the measured values, so a sequence's
expected reward is computed without sampling. A batch of B beliefs is a batch of B copies, stepped with the env's
own batched functions (``transition.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from infonav_gym.compiled import stacked
from infonav_gym.envs.active_localization.transition import (
    N_PRIMITIVES,
    PRIMITIVE_NAMES,
    PRIMITIVE_OFFSETS_RAD,
    decode_actions,
    landmark_models,
    layout_of_actions,
    primitive_commands,
    step_rewards,
)
from infonav_gym.estimation import batched
from infonav_gym.estimation.state import BeliefBatch
from infonav_gym.information import largest_position_std
from infonav_gym.world.visibility import in_coverage

__all__ = ["N_PRIMITIVES", "PRIMITIVE_NAMES", "PRIMITIVE_OFFSETS_RAD", "ActivePlanningModel", "Belief"]


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
    """The planning model of one sub-env of ``ActiveLocalizationVectorEnv`` (``env.planning_model(copy)``).

    What a look-ahead agent uses: ``belief()``, ``plan_decision(belief)``, ``plan_step(belief, actions)``,
    ``position_std(covariances)``, ``n_primitives``, ``max_position_std_m`` and ``idle_primitive``. It reads the
    sub-env's episode (goal, landmarks, obstacles, estimator state) when called, so one model serves a whole run.
    """

    idle_primitive = None  # no primitive stands still: every one drives
    n_primitives = N_PRIMITIVES
    position_std = staticmethod(largest_position_std)  # on (B, 3, 3) covariances

    def __init__(self, env, copy: int = 0):
        self._env, self._copy = env, copy

    @property
    def config(self) -> dict:
        return self._env.config

    @property
    def max_position_std_m(self) -> float:
        """The failure bound on the largest position standard deviation [m] (config ``max_position_std_m``)."""
        return self.config["max_position_std_m"]

    def belief(self) -> Belief:
        """The estimator's state at the current decision as a batch of one (visibility: from the true pose)."""
        return self._env.belief(self._copy)

    def plan_decision(self, belief: Belief) -> tuple[np.ndarray, np.ndarray]:
        """``(action_mask (B, n), action_information_gain (B, n))`` at each belief, as ``info`` would give them.

        Finished beliefs have only no-observation actions valid, all with gain 0.
        """
        landmarks = self._env.episode_landmarks(self._copy)
        _, H, R = landmark_models(
            self._env.sensor, belief.pose, np.broadcast_to(landmarks, (len(belief), *landmarks.shape))
        )
        observable = belief.visible & ((belief.observations_left > 0) & ~belief.done)[:, None]
        gains = np.zeros(observable.shape)
        rows = np.flatnonzero(observable.any(axis=1))
        if rows.size:
            gains[rows] = batched.landmark_information_gains(
                belief.covariance[rows], H[rows], R[rows], check_input=False
            )
        return layout_of_actions(observable, gains)

    def plan_step(self, belief: Belief, actions) -> tuple[Belief, np.ndarray]:
        """Predict one step of each belief under its action: ``(next beliefs, expected rewards (B,))``.

        The model the env's own transition follows, with the unknowns replaced by their expectation: the
        observation's MI is exact (it does not depend on the measured value), the motion is the primitive's
        command from the estimated pose without collisions or noise, progress and the goal are judged from the
        estimated position, and visibility after the move from the predicted pose (range, field of view and
        the round obstacles). An invalid action is the env's no-op; a finished belief stays put and earns 0.
        """
        cfg, env, copy = self.config, self._env, self._copy
        landmarks, goal = env.episode_landmarks(copy), env.episode_goal(copy)
        landmark, primitives = decode_actions(actions)
        done, B = belief.done, len(belief)
        observe = (landmark >= 0) & ~done & (belief.observations_left > 0)
        observe &= belief.visible[np.arange(B), np.maximum(landmark, 0)]
        valid = ((landmark < 0) | observe) & ~done
        covariance, mutual_information = belief.covariance.copy(), np.zeros(B)
        rows = np.flatnonzero(observe)
        if rows.size:  # the expected update: the measurement as predicted (a zero residual)
            _, H, R = landmark_models(env.sensor, belief.pose[rows], landmarks[landmark[rows]][:, None])
            gains = batched.landmark_information_gains(covariance[rows], H, R, check_input=False)
            mutual_information[rows] = gains[:, 0]
            no_residual = np.zeros((rows.size, 2))
            covariance[rows] = batched.range_bearing_update(
                belief.pose[rows], covariance[rows], no_residual, no_residual, H[:, 0], R[:, 0], check_input=False
            )[1]
        commands = primitive_commands(cfg, goal, belief.pose, np.where(valid, primitives, -1))
        pose, predicted = batched.predict_pose(
            belief.pose, covariance, commands, cfg["time_step_s"], env.odometry_covariance, check_input=False
        )
        covariance = np.where(done[:, None, None], covariance, predicted)
        pose = np.where(done[:, None], belief.pose, pose)
        goals = stacked(goal, (B, 2))
        arrays = (goals, covariance, mutual_information, observe, valid, ~done)
        _, rewards, reached, failed = step_rewards(cfg, belief.pose[:, :2], pose[:, :2], *arrays)
        following = Belief(
            pose=pose,
            covariance=covariance,
            observations_left=belief.observations_left - observe,
            visible=self._model_visibility(pose),
            done=done | reached | failed,
        )
        return following, rewards

    def _model_visibility(self, poses: np.ndarray) -> np.ndarray:
        """Which landmarks each pose (B, 3) sees: in coverage (the env's ``in_coverage``), no round obstacle of the
        known map in the way (B, K)."""
        landmarks = self._env.episode_landmarks(self._copy)
        centers, radii = self._env.episode_obstacles(self._copy)
        targets = np.broadcast_to(landmarks, (len(poses), *landmarks.shape))
        visible = in_coverage(self._env.sensor, poses, targets)
        if len(radii):
            offsets = targets - poses[:, None, :2]  # (B, K, 2)
            to_center = centers[None, None] - poses[:, None, None, :2]  # (B, 1, O, 2)
            length_sq = np.maximum(np.hypot(offsets[..., 0], offsets[..., 1]) ** 2, 1e-12)[..., None]
            along = np.clip(np.einsum("bkoi,bki->bko", to_center, offsets) / length_sq, 0.0, 1.0)
            closest = along[..., None] * offsets[:, :, None, :] - to_center
            blocked = np.einsum("bkoi,bkoi->bko", closest, closest) <= radii**2
            visible &= ~blocked.any(axis=2)
        return visible
