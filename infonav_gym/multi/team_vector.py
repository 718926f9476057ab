"""``TeamVectorEnv``: what the native vector envs of the team envs share (the step cycle, DGPS, relative poses).

A team vector env batches N copies of a PettingZoo team env of R robots on stacked arrays: observations
(N, R, ...), one action per copy and robot (N, R), joint EKF states ``x`` (N, 3R) and covariances ``P``. Its
``_build`` hook (after ``_setup``, which merges the config) checks its own keys, then calls ``_setup_team`` with
its spaces and sensors; its PettingZoo env is the N = 1 view (``multi.parallel_view``) and ``render()`` draws its
copy 0 from ``_scene_frame()``. It fills the hooks ``_reset_copies``, ``_reset_record``, ``_act``, ``_decide``,
``_outputs`` and ``_restarted``; the cycle of ``reset`` and ``step`` (with the autoreset modes), the action checks,
the DGPS fixes and the stacked relative-pose update are here.
"""

from __future__ import annotations

import abc
import math

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from infonav_gym.compiled import contiguous, kernel, stacked
from infonav_gym.envs.base import accepts_action
from infonav_gym.envs.noise_streams import NoiseStreams
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.envs.vector_base import InfoNavVectorEnv, accepted_actions, outside_action_space
from infonav_gym.envs.vector_infos import final_step_infos
from infonav_gym.estimation import batched
from infonav_gym.estimation.kernels import kalman_updates, pose_block_log_det, predict_poses
from infonav_gym.estimation.state import POSE_DIM, block_diagonal
from infonav_gym.geometry import wrap_angle_kernel as wrap
from infonav_gym.information import log_det_of, mutual_information_kernel
from infonav_gym.multi.team_sensing import NO_OBSERVATION, gps_available, gps_schedule
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.relative_pose import relative_pose_measured
from infonav_gym.world.world_batch import WorldBatch

MASK_KEY = 'info["action_mask"]'
ODOMETRY_NOISE, GPS_NOISE, RELATIVE_NOISE = 0, 1, 2  # ``_noise`` index of each sensor's streams (more may follow)


class TeamVectorEnv(InfoNavVectorEnv, abc.ABC):
    """Base of the native vector envs of the PettingZoo team envs (``CooperativeLocalizationVectorEnv``, ...).

    Attributes set by ``_setup_team``: ``agents`` (the team's robots R), ``max_cycles``, the spaces, the team's
    ``_pairs`` (``SensingPairs``), ``_worlds`` (a ``WorldBatch``), ``_noise`` (one ``NoiseStreams`` per sensor
    generator of an episode, in the order ``start_episode`` spawns them), ``_x``, ``_P``, ``_gps_available``
    (N, R) and ``_elapsed`` (N,). ``team_info_keys`` are the info keys of the whole team, (N,) arrays; every
    other key of the parallel env's ``infos[agent]`` is (N, R, ...).
    """

    team_info_keys = frozenset({"time_s"})
    AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED)
    traits: EnvTraits  # ``traits.noop_action``: the action that does nothing, always valid; a masked one becomes it

    def _setup_team(self, observation_space, action_space, pairs, gps, odometry, more_noise_widths=()) -> None:
        """Set the spaces and the copies' arrays of a team of ``len(gps)`` robots (after ``_setup``).

        Args:
            observation_space: one robot's ``Box``.
            action_space: one robot's ``Discrete``.
            pairs: the team's (observer, target) pairs (``SensingPairs``).
            gps: each robot's ``GPSSensor`` (with its outage spans), or None without DGPS.
            odometry: every robot's odometry sensor.
            more_noise_widths: the draw widths of the episode's generators after odometry, DGPS and relative poses.
        """
        n_robots, num_envs = len(gps), self.num_envs
        self.agents = [f"robot_{k}" for k in range(n_robots)]
        self.max_cycles = self.config["max_cycles"]
        self.single_observation_space, self.single_action_space = observation_space, action_space
        low, high = observation_space.low, observation_space.high
        shape = (num_envs, n_robots, *low.shape)
        self.observation_space = spaces.Box(np.broadcast_to(low, shape), np.broadcast_to(high, shape), dtype=np.float32)
        self.action_space = spaces.MultiDiscrete(np.full((num_envs, n_robots), action_space.n))
        self._pairs = pairs
        self._pair_index = np.full((n_robots, n_robots + 1), -1)  # robot, teammate choice -> its pair
        self._pair_index[pairs.observers, pairs.targets + 1] = np.arange(len(pairs.observers))
        self._has_gps, self._outages = gps_schedule(gps)
        self._gps = GPSSensor(self.config["gps_std_m"])  # every receiver's noise; the schedules are _outages
        self._gps_covariance = self._gps.noise_covariance()
        self._cross_covariances = self.config.get("estimator", "joint") == "joint"  # a team env may drop them
        self._odometry = odometry
        self._odometry_covariances = np.repeat(odometry.noise_covariance()[None], n_robots, axis=0)
        self._worlds = WorldBatch(num_envs)
        widths = (2 * n_robots, 2, POSE_DIM, *more_noise_widths)
        self._noise = tuple(NoiseStreams(num_envs, width) for width in widths)
        dim = POSE_DIM * n_robots
        self._x, self._P = np.zeros((num_envs, dim)), np.zeros((num_envs, dim, dim))
        self._gps_available = np.zeros((num_envs, n_robots), dtype=bool)
        self._zone_centers, self._zone_radii_sq = np.zeros((num_envs, 0, 2)), np.zeros((num_envs, 0))
        self._slots = (np.arange(num_envs)[:, None], np.arange(n_robots))  # index of every (copy, robot)

    # ------------------------------------------------------------------ the state, for harnesses and tests

    def scenario(self, copy: int = 0):
        """The ``Scenario`` of copy ``copy``'s episode."""
        return self._worlds.scenario(copy)

    @property
    def true_poses(self) -> np.ndarray:
        """Every copy's true robot poses (N, R, 3) [m, m, rad] (a copy)."""
        return self._worlds.poses.copy()

    def joint_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Every copy's joint EKF state ``x`` (N, 3R) and covariance ``P`` (N, 3R, 3R) (copies)."""
        return self._x.copy(), self._P.copy()

    # ------------------------------------------------------------------ reset

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset every copy: seed ``s`` gives copy ``i`` the seed ``s + i``; a list gives one seed (or None) each.

        Raises:
            ValueError: for a seed that is not None, an int >= 0 or a list of N such seeds, or any options.
        """
        self._seed_sub_envs(seed, options)
        self._reset_copies(np.arange(self.num_envs))
        self._prev_done[:] = False
        self._decide()
        return self._rendered(self._outputs(self._reset_record()))

    def _start_copy(self, copy: int, scenario, poses, covariances, generators) -> None:
        """Copy ``copy`` starts an episode of ``scenario``: its world, sensor streams and joint EKF prior."""
        self._worlds.reset_copy(copy, scenario)
        for streams, generator in zip(self._noise, generators):
            streams.restart(copy, generator)
        self._x[copy], self._P[copy] = poses.ravel(), block_diagonal(covariances)

    def _started(self, copies: np.ndarray) -> None:
        """``copies`` have started their episodes (``_start_copy``): time 0, their DGPS zones and first fixes."""
        self._elapsed[copies] = 0
        self._zone_centers, self._zone_radii_sq = self._gps_denied_zones()
        self._gps_fixes(copies)

    def _gps_denied_zones(self) -> tuple[np.ndarray, np.ndarray]:
        """Every copy's GPS-denied zones: centres (N, Z, 2) [m] and squared radii (N, Z) [m^2] (-1: padding)."""
        zones = [self._worlds.scenario(copy).gps_denied_zones for copy in range(self.num_envs)]
        centers = np.zeros((self.num_envs, max(map(len, zones)), 2))
        radii_sq = np.full(centers.shape[:2], -1.0)
        for copy, copy_zones in enumerate(zones):
            for slot, zone in enumerate(copy_zones):
                centers[copy, slot], radii_sq[copy, slot] = zone.center, zone.radius**2
        return centers, radii_sq

    # ------------------------------------------------------------------ step

    def step(self, actions):
        """Act in every copy (reset those whose episode ended at the last step, with ``NEXT_STEP``; see the class).

        Raises:
            ValueError: for actions that are not (N, R) integers of the action space, or, with
                ``invalid_action="raise"``, a masked action (each naming its copy and robot).
        """
        if self._decision is None:
            raise RuntimeError(f"{self.owner_name}: call reset() before step()")
        actions = self._checked_actions(actions)
        resetting = self._prev_done.copy()
        chosen, invalid = self._chosen_actions(actions, ~resetting)
        last, rewards, terminated = self._act(chosen, invalid, ~resetting)
        if resetting.any():
            self._reset_copies(np.flatnonzero(resetting))
        self._decide()
        truncated = ~resetting & ~terminated & (self._elapsed >= self.max_cycles)
        ended = terminated | truncated
        observations, info = self._outputs(last)
        if self.autoreset_mode == AutoresetMode.SAME_STEP and ended.any():
            final_infos = final_step_infos(observations, info, ended)
            self._reset_copies(np.flatnonzero(ended))
            self._decide()
            observations, info = self._outputs(self._restarted(last, ended))
            info.update(final_infos)
        elif self.autoreset_mode == AutoresetMode.NEXT_STEP:
            self._prev_done = ended
        # DISABLED: a copy whose episode ended goes on stepping until reset() (its view refuses to)
        self._rendered((observations, info))
        n_robots = len(self.agents)
        return (
            observations,
            rewards,
            np.repeat(terminated[:, None], n_robots, axis=1),
            np.repeat(truncated[:, None], n_robots, axis=1),
            info,
        )

    def _checked_actions(self, actions) -> np.ndarray:
        """The actions as an int64 array (N, R) (``_chosen_actions`` checks that they are in the space)."""
        array = np.asarray(actions)
        n_robots, top = len(self.agents), self.single_action_space.n - 1
        if array.shape != (self.num_envs, n_robots) or array.dtype.kind not in "iu":
            raise ValueError(
                f"actions of {self.owner_name} must be an integer array of shape ({self.num_envs}, {n_robots}), "
                f"one per copy and robot, in [0, {top}]; got {array.dtype} of shape {array.shape}"
            )
        return array.astype(np.int64, copy=False)

    def _chosen_actions(self, actions: np.ndarray, acting: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each robot's executed action (the no-op for a masked one and in a resetting copy), and which were masked
        (``accepted_actions`` over the copies' robots)."""
        mask, noop = self._decision.action_mask, self.traits.noop_action
        n_robots = actions.shape[1]
        flat_mask, resetting = mask.reshape(-1, mask.shape[-1]), np.repeat(~acting, n_robots)
        accepted, outside = accepted_actions(actions.reshape(-1), flat_mask, resetting)
        if outside >= 0:
            copy, robot = divmod(outside, n_robots)
            where = f"{self.agents[robot]} in sub-env {copy}"
            raise outside_action_space(actions[copy, robot], where, self.single_action_space)
        accepted = accepted.reshape(actions.shape)
        invalid = acting[:, None] & (accepted < 0)
        for copy, robot in np.argwhere(invalid).tolist() if invalid.any() else ():
            where = f"{self.agents[robot]} in sub-env {copy}"  # a PettingZoo view checks its agents' actions first
            accepts_action(int(actions[copy, robot]), mask[copy, robot], self.config["invalid_action"], MASK_KEY, where)
        return np.where(accepted >= 0, accepted, noop), invalid

    def _relative_update(self, copies: np.ndarray, chosen: np.ndarray, decision) -> list:
        """Fuse the teammate choices ``chosen`` (n, R) (``NO_OBSERVATION`` or ``1 + j`` for robot j) of ``copies`` (n,)
        at the ``decision``'s candidates as one stacked update per copy; the joint MI (n,), each robot's own-pose MI
        (n, R) [nats] and its x, y, heading standard deviations after (n, R, 3) (``relative_updates``: MI 0 and the
        prior's std in a copy without observations; all copies are views, no copies)."""
        noise = self._noise[RELATIVE_NOISE].take_many(copies, chosen != NO_OBSERVATION)
        rows = self._rows(copies)
        candidates = (decision.geometry, decision.predicted, decision.H_observer, decision.H_target, decision.R)
        self._x[rows], self._P[rows], *brought = relative_updates(
            self._x[rows],
            self._P[rows],
            chosen,
            self._pair_index,
            self._pairs.targets,
            self._pairs.noise,
            *(contiguous(candidate[rows]) for candidate in (*candidates, decision.pose_log_det)),
            noise,
            self._cross_covariances,
        )
        if np.isnan(brought[0]).any():
            raise ValueError("the joint covariance after the relative-pose updates is not positive definite")
        return brought

    def _predict(self, copies: np.ndarray, controls: np.ndarray, dt: float) -> None:
        """Predict the EKFs of ``copies`` with noisy odometry of the executed ``controls`` (n, R, 2) over ``dt`` [s]."""
        noise = self._noise[ODOMETRY_NOISE].take(copies).reshape(controls.shape)
        readings = self._odometry.measure_with_noise(controls, noise)
        rows = self._rows(copies)
        x, P = contiguous(self._x[rows]), contiguous(self._P[rows])  # ``JointEKF.predict`` on the compiled core
        covariances = stacked(self._odometry_covariances, (*controls.shape, 2))
        self._x[rows], self._P[rows] = predict_poses(x, P, readings, float(dt), covariances)

    def _gps_fixes(self, copies: np.ndarray) -> None:
        """Which robots of ``copies`` have a DGPS fix now (schedule, zones), and their update."""
        within = self._rows(copies)
        positions = self._worlds.poses[within, :, :2]
        available = self.gps_available(copies, positions, self._elapsed[within] * self.config["time_step_s"])
        self._gps_available[within] = available
        if not available.any():
            return
        fixes = self._gps.measure_with_noise(positions, self._noise[GPS_NOISE].take_many(copies, available))
        self._x[within], self._P[within] = batched.gps_update(  # copies without a fix come back unchanged
            self._x[within],
            self._P[within],
            fixes,
            self._gps_covariance,
            available,
            cross_covariances=self._cross_covariances,
            check_input=False,
        )

    def gps_available(self, copies: np.ndarray, positions: np.ndarray, time_s: np.ndarray) -> np.ndarray:
        """Which robots at ``positions`` (n, R, 2) [m] in ``copies`` (n,) have a DGPS fix at ``time_s`` (n,) [s]: they
        carry DGPS, are in none of their copy's GPS-denied zones and in no outage span (n, R) bool."""
        zones = self._zone_centers, self._zone_radii_sq
        return gps_available(copies, contiguous(positions), *zones, self._has_gps, self._outages, time_s)

    def action_masks(self) -> np.ndarray:
        """The valid actions of each copy and robot as bool (N, R, A) (the no-op is always valid)."""
        if self._decision is None:
            raise RuntimeError(f"{self.owner_name}: call reset() before action_masks()")
        return self._decision.action_mask.astype(bool)

    # ------------------------------------------------------------------ the hooks

    @abc.abstractmethod
    def _reset_copies(self, copies: np.ndarray) -> None:
        """Hook: start a new episode in each of ``copies`` from its own generator (``_start_copy`` for each, then
        ``_started``)."""

    @abc.abstractmethod
    def _reset_record(self):
        """Hook: the step record (what ``_outputs`` reads) of a reset of every copy."""

    @abc.abstractmethod
    def _act(self, chosen: np.ndarray, invalid: np.ndarray, acting: np.ndarray) -> tuple:
        """Hook: the ``acting`` copies (N,) bool take the ``chosen`` actions (N, R) (``invalid`` ones are no-ops).

        Returns:
            ``(record, rewards (N, R), terminated (N,) bool)``: the step record for ``_outputs``, 0 and False for
            the copies not acting; ``_elapsed`` counts the step.
        """

    @abc.abstractmethod
    def _decide(self) -> None:
        """Hook: set ``_decision`` (with ``action_mask`` (N, R, A)) at every copy's prior."""

    @abc.abstractmethod
    def _outputs(self, record) -> tuple[np.ndarray, dict]:
        """Hook: the observations (N, R, ...) and infos of every copy at the current decision, after ``record``."""

    @abc.abstractmethod
    def _restarted(self, record, copies: np.ndarray):
        """Hook: ``record`` with the (N,) bool ``copies`` reset since (their reset info: no action, no reward)."""


@kernel
def relative_updates(
    x, P, chosen, pair_index, targets, parameters, geometry, predicted, H_o, H_t, R, log_det, noise, cross
):
    """``JointEKF.relative_pose_update`` of n copies with their robots' teammate choices, and what it brought.

    Robot k of copy c observes pair ``pair_index[k, chosen[c, k]]`` (-1: none): its true relative pose ``geometry``
    plus the sensor's noise (``relative_poses_with_noise`` of its ``parameters`` and the standard normals ``noise[c,
    k]``), fused at the prior's ``predicted``, ``H_o``, ``H_t`` and ``R`` in slot order (``kalman_updates``). Returns
    ``(x, P, joint_mi (n,), own_mi (n, R), pose_std (n, R, 3))``: the MI on the joint state and on each robot's pose
    (prior: ``log_det`` (n, R)) [nats], NaN where a determinant is not > 0, and each robot's std after. A copy
    without observations keeps its x and P: MI 0 (its joint log-determinants are not computed).
    """
    n_copies, n = x.shape
    n_robots = chosen.shape[1]
    residuals, slot_R = np.zeros((n_copies, n_robots, POSE_DIM)), np.zeros((n_copies, n_robots, POSE_DIM, POSE_DIM))
    H, observed = np.zeros((n_copies, n_robots, POSE_DIM, n)), np.zeros((n_copies, n_robots), np.bool_)
    measured, observations = np.empty(POSE_DIM), np.zeros(n_copies, np.int64)
    for c in range(n_copies):
        for robot in range(n_robots):
            pair = pair_index[robot, chosen[c, robot]]
            if pair < 0:
                continue
            observed[c, robot] = True
            observations[c] += 1
            target = targets[pair]
            relative_pose_measured(geometry[c, pair], parameters[pair], noise[c, robot], measured)
            for i in range(POSE_DIM):
                residual = measured[i] - predicted[c, pair, i]
                residuals[c, robot, i] = wrap(residual) if i else residual
                for j in range(POSE_DIM):
                    H[c, robot, i, POSE_DIM * robot + j] = H_o[c, pair, i, j]
                    H[c, robot, i, POSE_DIM * target + j] = H_t[c, pair, i, j]
                    slot_R[c, robot, i, j] = R[c, pair, i, j]
    x_new, P_new = kalman_updates(x, P, residuals, H, slot_R, observed, n_robots, cross)
    joint_mi, own_mi, pose_std = np.empty(n_copies), np.empty((n_copies, n_robots)), np.empty(residuals.shape)
    block = np.empty((POSE_DIM, POSE_DIM))
    for c in range(n_copies):
        joint_mi[c] = mutual_information_kernel(log_det_of(P[c]), log_det_of(P_new[c])) if observations[c] else 0.0
        for robot in range(n_robots):
            own_mi[c, robot] = mutual_information_kernel(
                log_det[c, robot], pose_block_log_det(P_new[c], POSE_DIM * robot, block)
            )
            for i in range(POSE_DIM):
                pose_std[c, robot, i] = math.sqrt(P_new[c, POSE_DIM * robot + i, POSE_DIM * robot + i])
    return x_new, P_new, joint_mi, own_mi, pose_std
