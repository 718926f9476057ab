"""``CooperativeLocalizationVectorEnv``: N copies of ``cooperative_localization_v0`` stepped at once on stacked arrays.

``make_vector_env("cooperative_localization_v0", num_envs=N, **config)`` returns it. The joint estimation
(prediction, DGPS and relative-pose updates, expected gains, log-determinants) and the robot-robot line of sight
run batched over the copies (``estimation.batched``, ``world.visibility``), the physics in a ``WorldBatch`` (numpy
free motion, a copy's own Pymunk space for its contact steps) and the sensor noise from one stream per copy and
sensor (``NoiseStreams``: the parallel env's generators, drawn ahead, handed out in its order).
So copy ``i`` after ``reset(seed=s)`` gives the numbers of ``parallel_env()`` after ``reset(seed=s + i)``.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from infonav_gym.envs.base import accepts_action
from infonav_gym.envs.noise_streams import NoiseStreams
from infonav_gym.envs.vector_base import InfoNavVectorEnv
from infonav_gym.envs.vector_infos import final_step_infos
from infonav_gym.estimation import batched
from infonav_gym.estimation.ekf import POSE_DIM, block_diagonal
from infonav_gym.multi.cooperative_localization import (
    NO_OBSERVATION,
    CooperativeLocalizationEnv,
    start_episode,
    team_observations,
)
from infonav_gym.multi.cooperative_localization_batch import TeamDecision, TeamSightLines, TeamStep, team_info
from infonav_gym.multi.team_sensing import gps_available, gps_schedule
from infonav_gym.sensors.gps import GPSSensor
from infonav_gym.sensors.relative_pose import relative_poses_with_noise
from infonav_gym.world.visibility import StaticGeometry
from infonav_gym.world.world_batch import WorldBatch

MASK_KEY = 'info["action_mask"]'


class CooperativeLocalizationVectorEnv(InfoNavVectorEnv, single_env=CooperativeLocalizationEnv):
    """N copies of ``CooperativeLocalizationEnv`` (see it for the spaces, rewards and config keys), batched.

    ## Vector API
    ``agents`` are the team's robots R; ``single_observation_space`` / ``single_action_space`` one robot's.
    ``step`` takes one action per copy and robot (N, R) and returns observations (N, R, 10 + 5R), rewards,
    ``terminated`` and ``truncated`` (N, R). Infos hold the parallel env's per-agent keys as arrays with
    leading (N, R) (``time_s``: (N,)), each with Gymnasium's ``_key`` mask (N,); ``info["action_mask"]`` is
    (N, R, R + 1). ``action_masks()`` gives the (N, R, R + 1) bool masks for ``MaskablePPO``.

    ## Autoreset
    ``metadata["autoreset_mode"]``, chosen by ``autoreset_mode``. ``NEXT_STEP`` (the default, as Gymnasium's
    ``CartPoleVectorEnv``): the step after a copy's episode ended resets it (its actions are ignored), with
    rewards 0, not terminated nor truncated, and its reset info (``reward_terms`` masked out). ``SAME_STEP``:
    the step that ends an episode resets the copy at once and returns its reset observation; the last
    observation is ``info["final_obs"]`` (an object array (N,) of (R, 10 + 5R) arrays, None for the others) and
    the last info ``info["final_info"]``, masked by ``info["_final_obs"]`` / ``info["_final_info"]`` (N,).
    A copy reset this way continues its own generator, as the parallel env's ``reset()`` without a seed does.

    ## Arguments
    ``num_envs`` (N >= 1), ``autoreset_mode`` (an ``AutoresetMode``, its value or its name ``"same_step"``) and
    any key of ``CooperativeLocalizationEnv.default_config()``, checked as the parallel env checks them.
    ``render_mode`` (``"rgb_array"`` or ``"human"``): ``render()`` draws copy 0, as its parallel env would
    (``FirstCopyView``: a parallel env kept in step with copy 0, one parallel step per vector step).
    """

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **config,
    ):
        self._single = self._configure(num_envs, render_mode, autoreset_mode, config)
        self.agents = list(self._single.possible_agents)
        n_robots = len(self.agents)
        self.max_cycles = self.config["max_cycles"]
        self.single_observation_space = self._single.observation_space(self.agents[0])
        self.single_action_space = self._single.action_space(self.agents[0])
        low, high = self.single_observation_space.low, self.single_observation_space.high
        shape = (num_envs, n_robots, *low.shape)
        self.observation_space = spaces.Box(np.broadcast_to(low, shape), np.broadcast_to(high, shape), dtype=np.float32)
        self.action_space = spaces.MultiDiscrete(np.full((num_envs, n_robots), n_robots + 1))
        self._pairs = self._single.pairs
        self._pair_index = np.full((n_robots, n_robots + 1), -1)
        self._pair_index[self._pairs.observers, self._pairs.targets + 1] = np.arange(len(self._pairs.observers))
        self._has_gps, self._outages = gps_schedule(self._single.gps)
        self._gps = GPSSensor(self.config["gps_std_m"])  # every receiver's noise; the schedules are _outages
        self._odometry = self._single.odometry
        self._odometry_covariances = np.repeat(self._odometry.noise_covariance()[None], n_robots, axis=0)
        self._worlds = WorldBatch(num_envs)
        self._noise = (NoiseStreams(num_envs, 2 * n_robots), NoiseStreams(num_envs, 2), NoiseStreams(num_envs, 3))
        self._geometries: list[StaticGeometry | None] = [None] * num_envs
        self._sight = None
        dim = POSE_DIM * n_robots
        self._x, self._P = np.zeros((num_envs, dim)), np.zeros((num_envs, dim, dim))
        self._gps_available = np.zeros((num_envs, n_robots), dtype=bool)
        self._zone_centers, self._zone_radii_sq = np.zeros((num_envs, 0, 2)), np.zeros((num_envs, 0))
        self._elapsed = np.zeros(num_envs, dtype=int)
        self._prev_done = np.zeros(num_envs, dtype=bool)

    # ------------------------------------------------------------------ reset

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset every copy: seed ``s`` gives copy ``i`` the seed ``s + i``; a list gives one seed (or None) each.

        Raises:
            ValueError: for a seed that is not None, an int >= 0 or a list of N such seeds, or any options.
        """
        self._seed_sub_envs(seed, options)
        everyone = np.arange(self.num_envs)
        self._reset_copies(everyone)
        self._prev_done[:] = False
        self._decide()
        return self._outputs(TeamStep.of_reset(*self._gps_available.shape))

    def _reset_copies(self, copies: np.ndarray) -> None:
        """Start a new episode in each of ``copies`` from its own generator, as the parallel env's reset does."""
        owner = type(self._single).__name__
        self._view_restarts(copies)
        for copy in copies.tolist():
            scenario, poses, covariances, *generators = start_episode(self.config, self._np_randoms[copy], owner)
            self._worlds.reset_copy(copy, scenario)
            for streams, generator in zip(self._noise, generators):  # odometry, DGPS, relative poses
                streams.restart(copy, generator)
            self._x[copy], self._P[copy] = poses.ravel(), block_diagonal(covariances)
            self._geometries[copy] = StaticGeometry.from_scenario(scenario, self._worlds.wall_thickness_m)
        self._elapsed[copies] = 0
        self._zone_centers, self._zone_radii_sq = self._gps_denied_zones()
        if len(self._pairs.observers):
            self._sight = TeamSightLines.of_copies(self._geometries, self._pairs)
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
            raise RuntimeError(f"{type(self).__name__}: call reset() before step()")
        actions = self._checked_actions(actions)
        resetting = self._prev_done.copy()
        chosen, invalid = self._chosen_actions(actions, ~resetting)
        if self._view is not None and not resetting[0]:
            self._view.step(dict(zip(self.agents, actions[0].tolist())))
        own_mi, team_mi, updated_std = self._observe(chosen)
        acting = np.flatnonzero(~resetting)
        self._elapsed[acting] += 1
        self._advance(acting)
        if resetting.any():
            self._reset_copies(np.flatnonzero(resetting))
        self._decide()
        last = TeamStep(~resetting, chosen, invalid, own_mi, team_mi, updated_std)
        weight = self.config["team_reward"]
        rewards = np.where(last.stepped[:, None], (1.0 - weight) * own_mi + weight * team_mi, 0.0)
        ended = last.stepped & (self._elapsed >= self.max_cycles)
        observations, info = self._outputs(last)
        if self.autoreset_mode == AutoresetMode.SAME_STEP and ended.any():
            final_infos = final_step_infos(observations, info, ended)
            self._reset_copies(np.flatnonzero(ended))
            self._decide()
            observations, info = self._outputs(_restarted(last, ended))
            info.update(final_infos)
        else:
            self._prev_done = ended
        truncated = np.repeat(ended[:, None], len(self.agents), axis=1)
        return observations, rewards, np.zeros_like(truncated), truncated, info

    def _checked_actions(self, actions) -> np.ndarray:
        array = np.asarray(actions)
        n_robots = len(self.agents)
        if array.shape != (self.num_envs, n_robots) or array.dtype.kind not in "iu":
            raise ValueError(
                f"actions of {type(self).__name__} must be an integer array of shape ({self.num_envs}, {n_robots}), "
                f"one per copy and robot, in [0, {n_robots}]; got {array.dtype} of shape {array.shape}"
            )
        outside = np.argwhere((array < 0) | (array > n_robots))
        if outside.size:
            copy, robot = outside[0].tolist()
            raise ValueError(
                f"action {array[copy, robot]} of {self.agents[robot]} in sub-env {copy} is not in the action space "
                f"{self.single_action_space}: expected an integer in [0, {n_robots}]"
            )
        return array.astype(int)

    def _chosen_actions(self, actions: np.ndarray, acting: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each robot's executed action (the no-op for a masked one and in a resetting copy), and which were masked."""
        mask = self._decision.action_mask
        copies, robots = np.ogrid[: self.num_envs, : len(self.agents)]
        valid = mask[copies, robots, actions].astype(bool)
        invalid = acting[:, None] & ~valid
        for copy, robot in np.argwhere(invalid).tolist():
            where = f"{self.agents[robot]} in sub-env {copy}"
            accepts_action(int(actions[copy, robot]), mask[copy, robot], self.config["invalid_action"], MASK_KEY, where)
        return np.where(acting[:, None] & valid, actions, NO_OBSERVATION), invalid

    def _observe(self, chosen: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fuse each copy's chosen observations as one stacked update; the own and team MI (N, R) and the new std."""
        decision, n_robots = self._decision, len(self.agents)
        team_mi = np.zeros(self.num_envs)
        observed = chosen != NO_OBSERVATION
        measured = np.flatnonzero(observed.any(axis=1))
        if measured.size:
            observed = observed[measured]
            pair = self._pair_index[np.arange(n_robots), chosen[measured]]  # -1 (unused) where not observed
            rows = measured[:, None], pair
            joint_before = np.linalg.slogdet(self._P[measured])[1]
            self._x[measured], self._P[measured] = batched.relative_pose_update(
                self._x[measured],
                self._P[measured],
                np.broadcast_to(np.arange(n_robots), observed.shape),
                self._pairs.targets[pair],
                self._relative_measurements(measured, decision.geometry[rows], pair, observed),
                decision.predicted[rows],
                decision.H_observer[rows],
                decision.H_target[rows],
                decision.R[rows],
                observed,
                cross_covariances=self.config["estimator"] == "joint",
                check_input=False,
            )
            team_mi[measured] = 0.5 * (joint_before - np.linalg.slogdet(self._P[measured])[1])
        own_mi = 0.5 * (decision.pose_log_det - batched.pose_log_dets(self._P, n_robots, check_input=False))
        updated_std = np.sqrt(np.diagonal(self._P, axis1=1, axis2=2)).reshape(self.num_envs, n_robots, POSE_DIM)
        return own_mi, np.repeat(team_mi[:, None], n_robots, axis=1), updated_std

    def _relative_measurements(self, copies, geometry, pair, observed) -> np.ndarray:
        """Noisy relative poses (n, R, 3) of the observed slots (n, R) of ``copies``, in the parallel env's order."""
        noise = _draws_in_slot_order(self._noise[2], copies, observed, POSE_DIM)
        parameters = self._pairs.noise[pair]
        measured = relative_poses_with_noise(
            geometry.reshape(-1, POSE_DIM), parameters.reshape(-1, 5), noise.reshape(-1, 3)
        )
        return measured.reshape(geometry.shape)

    def _advance(self, copies: np.ndarray) -> None:
        """Move the robots of ``copies``, predict with their noisy odometry, then fuse the DGPS fixes available."""
        if not copies.size:
            return
        dt = self.config["time_step_s"]
        controls = self._worlds.step(dt, copies)
        readings = self._odometry.measure_with_noise(controls, self._noise[0].take(copies).reshape(controls.shape))
        self._x[copies], self._P[copies] = batched.predict_team(
            self._x[copies], self._P[copies], readings, dt, self._odometry_covariances, check_input=False
        )
        self._gps_fixes(copies)

    def _gps_fixes(self, copies: np.ndarray) -> None:
        """Which robots of ``copies`` have a DGPS fix now (schedule, zones), and their update."""
        time_s = self._elapsed[copies] * self.config["time_step_s"]
        positions = self._worlds.poses[copies, :, :2]
        offsets = positions[:, :, None] - self._zone_centers[copies, None]
        denied = np.any(np.einsum("crzi,crzi->crz", offsets, offsets) <= self._zone_radii_sq[copies, None], axis=2)
        available = gps_available(self._has_gps, self._outages, denied, time_s)
        self._gps_available[copies] = available
        fixing = np.flatnonzero(available.any(axis=1))
        if not fixing.size:
            return
        rows, available = copies[fixing], available[fixing]
        fixes = self._gps.measure_with_noise(
            positions[fixing], _draws_in_slot_order(self._noise[1], rows, available, 2)
        )
        self._x[rows], self._P[rows] = batched.gps_update(
            self._x[rows],
            self._P[rows],
            fixes,
            self._gps.noise_covariance(),
            available,
            cross_covariances=self.config["estimator"] == "joint",
            check_input=False,
        )

    # ------------------------------------------------------------------ outputs

    def _decide(self) -> None:
        self._decision = TeamDecision.at_prior(
            self._pairs, self._sight, self._worlds.poses, self._x, self._P, self.config["team_reward"]
        )

    def _outputs(self, last: TeamStep) -> tuple[np.ndarray, dict]:
        """The observations and infos of every copy at the current decision, after ``last``."""
        decision = self._decision
        if last.pose_std_after_update is None:
            last = last._replace(pose_std_after_update=decision.pose_std)
        else:
            std = np.where(last.stepped[:, None, None], last.pose_std_after_update, decision.pose_std)
            last = last._replace(pose_std_after_update=std)
        observations = team_observations(
            self._x.reshape(self._worlds.poses.shape),
            decision.pose_std,
            decision.pose_log_det,
            self._gps_available,
            (self._elapsed / self.max_cycles)[:, None],
            decision.action_mask[..., 1:],
            self.single_observation_space,
            decision.action_information_gain if self.config["observe_gains"] else None,
        )
        time_s = self._elapsed * self.config["time_step_s"]
        return observations, team_info(decision, last, self._x, self._worlds.poses, self._gps_available, time_s)

    def action_masks(self) -> np.ndarray:
        """The valid actions of each copy and robot as bool (N, R, R + 1) (the no-op, 0, is always valid)."""
        if self._decision is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before action_masks()")
        return self._decision.action_mask.astype(bool)


def _restarted(last: TeamStep, copies: np.ndarray) -> TeamStep:
    """``last`` with the (N,) bool ``copies`` reset since: no action, no MI, not stepped."""
    rows = copies[:, None]
    return last._replace(
        stepped=last.stepped & ~copies,
        chosen=np.where(rows, NO_OBSERVATION, last.chosen),
        invalid=last.invalid & ~rows,
        own_mi=np.where(rows, 0.0, last.own_mi),
        team_mi=np.where(rows, 0.0, last.team_mi),
    )


def _draws_in_slot_order(streams: NoiseStreams, copies: np.ndarray, used: np.ndarray, width: int) -> np.ndarray:
    """One draw of ``width`` numbers for each used slot of ``copies`` (n, R, width), zeros elsewhere.

    A copy's used slots take its stream's next draws in slot order: what its parallel env draws in one
    ``standard_normal((k, width))`` call for its k used slots.
    """
    draws = np.zeros((*used.shape, width))
    turn_of = np.cumsum(used, axis=1) - 1  # each used slot's place among its copy's used slots
    counts = used.sum(axis=1)
    for turn in range(int(counts.max(initial=0))):
        rows = np.flatnonzero(counts > turn)
        slots = np.argmax(used[rows] & (turn_of[rows] == turn), axis=1)
        draws[rows, slots] = streams.take(copies[rows])
    return draws
