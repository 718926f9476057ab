"""``CooperativeExplorationVectorEnv``: ``cooperative_exploration_v0`` written once, N copies on stacked arrays.

``make_vector_env("cooperative_exploration_v0", num_envs=N, **config)`` returns it; its PettingZoo env
(``CooperativeExplorationEnv``, ``cooperative_exploration_v0.parallel_env``) is its N = 1 view without autoreset
(``multi.parallel_view``). The joint estimation (prediction, DGPS, relative-pose and landmark updates, expected
gains, log-determinants), the line of sight, the terrain maps and the scan gains run batched over the copies
(``estimation.batched``, ``world.visibility``, ``TerrainMapModel``), the physics in a ``WorldBatch`` driven by the
motions' turn and drive commands, and the sensor noise from one stream per copy and sensor (``NoiseStreams``), so
copy ``i`` after ``reset(seed=s)`` gives the numbers of ``parallel_env()`` after ``reset(seed=s + i)``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from infonav_gym.envs.metrics import EXPLORATION_METRICS
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.estimation import batched
from infonav_gym.estimation.models import range_bearing
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.multi.exploration_decision import (
    EXPLORATION_INFO_KEYS,
    ExplorationDecision,
    ExplorationStep,
    TeamSight,
    exploration_info,
    landmark_gains,
    range_bearing_noise,
)
from infonav_gym.multi.exploration_planning import (
    N_MOTIONS,
    NOOP_ACTION,
    STAY,
    ExplorationPlanningModel,
    action_gains,
    clear_motions,
    motion_plan,
    reward_terms,
    scan_gains,
    total_reward,
)
from infonav_gym.multi.exploration_team import (
    CONFIG_INTERVALS,
    REWARD_TERMS,
    ExplorationParts,
    exploration_config,
    exploration_observation_bounds,
    exploration_observations,
    start_episode,
)
from infonav_gym.multi.parallel_view import team_metadata
from infonav_gym.multi.team_decision import TeamDecision, observable_pairs
from infonav_gym.multi.team_observations import team_observation_bounds, team_observations
from infonav_gym.multi.team_paths import FirstCopyPaths
from infonav_gym.multi.team_vector import TeamVectorEnv
from infonav_gym.scene import SceneFrame
from infonav_gym.world.visibility import StaticGeometry

LANDMARK_NOISE = 3  # ``_noise`` index of the landmark measurements' streams (after odometry, DGPS, relative poses)
MAP_IMAGE_PIXELS_PER_CELL = 8
MAP_CELL_KB = 0.07  # [kB] a copy's memory per coverage-map cell, measured from 20 x 20 to 100 x 100 cells


class CopyState(NamedTuple):
    """One copy's estimator state at its current decision (copies of its arrays), for its planning model.

    Attributes:
        x: the joint EKF state (3R,); P: its covariance (3R, 3R).
        map_variances: the terrain map's cell variances (G,) [m^2].
        observations_left: each robot's sensing budget (R,).
        done: whether the copy's episode has ended (a robot lost, the coverage target reached, or out of time).
    """

    x: np.ndarray
    P: np.ndarray
    map_variances: np.ndarray
    observations_left: np.ndarray
    done: bool


class CooperativeExplorationVectorEnv(TeamVectorEnv):
    """N copies of ``cooperative_exploration_v0`` on stacked arrays: the env's one implementation.

    See ``CooperativeExplorationEnv`` (its N = 1 PettingZoo view) for the spaces, rewards and config keys.

    ## Vector API
    ``agents`` are the team's robots R; ``single_observation_space`` / ``single_action_space`` one robot's.
    ``step`` takes one action per copy and robot (N, R) and returns observations (N, R, 10 + 5R + 4L + 3 + G; A more
    with ``observe_gains``), rewards, ``terminated`` (a robot lost, or the coverage target reached) and ``truncated``
    (``max_cycles``) (N, R). Infos hold the parallel env's per-agent keys as arrays with leading (N, R), but the team's
    ``time_s``, ``coverage``, ``failed`` and ``success``: (N,); each with Gymnasium's ``_key`` mask (N,).
    ``info["action_mask"]`` and ``action_masks()`` (bool, for ``MaskablePPO``) are (N, R, 5 (1 + L + R)).
    ``planning_model(copy)`` is the planning model of copy ``copy`` (``multi.exploration_planning``).

    ## Autoreset
    As ``CooperativeLocalizationVectorEnv``: ``NEXT_STEP`` (the default) resets a copy at the step after its
    episode ended (its actions ignored, rewards 0, its reset info with ``reward_terms`` masked out);
    ``SAME_STEP`` at once, the last observation and info in ``info["final_obs"]`` and ``info["final_info"]``;
    ``DISABLED``: a copy goes on from its last state until ``reset()`` (what the PettingZoo view steps).

    ## Arguments
    ``num_envs`` (N >= 1), ``autoreset_mode`` (an ``AutoresetMode``, its value or its name ``"same_step"``) and
    any key of ``default_config()``. ``render_mode`` (``"rgb_array"`` or ``"human"``): ``render()`` draws copy 0:
    the field, the terrain map, each robot's truth, estimate, covariance and paths, and this step's observations.
    """

    metadata = {**team_metadata("cooperative_exploration_v0"), "autoreset_mode": AutoresetMode.NEXT_STEP}
    episode_metrics = EXPLORATION_METRICS
    traits = EnvTraits(
        kb_per_copy=75,  # [kB] at the defaults, between peak RSS growth and traced allocations
        reports_success=True,
        may_terminate=True,
        noop_action=NOOP_ACTION,
        idle_actions=frozenset({NOOP_ACTION}),  # stay, observe nothing
        reward_config_keys=("team_reward",),
        reward_terms=REWARD_TERMS,
        main_metric="success_rate",
        info_keys=EXPLORATION_INFO_KEYS,
    )
    team_info_keys = frozenset({"time_s", "coverage", "failed", "success"})

    @classmethod
    def default_config(cls) -> dict:
        """A fresh dict of every config key with its default."""
        return exploration_config()

    def copy_kb(self) -> float:
        """``kb_per_copy`` and ``MAP_CELL_KB`` a map cell beyond the default's."""
        side = min(self.config["map_cells_per_side"], CONFIG_INTERVALS["map_cells_per_side"].high)
        more_cells = side**2 - self.default_config()["map_cells_per_side"] ** 2
        return self.traits.kb_per_copy + MAP_CELL_KB * max(more_cells, 0)

    def _build(self) -> None:
        num_envs, cfg = self.num_envs, self.config
        self.parts = parts = ExplorationParts.of_config(cfg, self.owner_name)
        n_robots, n_landmarks, n_cells = len(parts.gps), cfg["n_landmarks"], parts.map_model.n_cells
        team_low, team_high = team_observation_bounds(n_robots, False)
        self._team_space = spaces.Box(team_low, team_high, dtype=np.float32)
        action_space = spaces.Discrete(N_MOTIONS * (1 + n_landmarks + n_robots))
        n_gains = action_space.n if cfg["observe_gains"] else 0
        low, high = exploration_observation_bounds(team_low, team_high, n_landmarks, n_cells, n_gains)
        observation_space = spaces.Box(low, high, dtype=np.float32)
        self._setup_team(observation_space, action_space, parts.pairs, parts.gps, parts.odometry, (2,))
        self._sight = TeamSight(tuple(parts.relative_sensors))
        self._landmarks = np.zeros((num_envs, n_landmarks, 2))
        self._geometries: list[StaticGeometry | None] = [None] * num_envs
        self._map_variances = np.zeros((num_envs, n_cells))
        self._coverage = np.zeros(num_envs)
        self._observations_left = np.zeros((num_envs, n_robots), dtype=int)
        self._lost = np.zeros((num_envs, n_robots), dtype=bool)
        self._success = np.zeros(num_envs, dtype=bool)
        self._planning_models: dict[int, ExplorationPlanningModel] = {}
        self._paths: FirstCopyPaths | None = None  # copy 0's paths and last observations, kept to draw them
        self._observed_pairs: list[tuple[int, int]] = []
        self._observed_landmarks: list[tuple[int, int]] = []

    # ------------------------------------------------------------------ the state, for harnesses and tests

    def static_geometry(self, copy: int = 0) -> StaticGeometry:
        """The walls and obstacles of copy ``copy``'s episode (one copy)."""
        return self._geometries[copy]

    @property
    def robot_radius_m(self) -> float:
        """The radius of every robot's disc [m]."""
        return self._worlds.robot_radius_m

    @property
    def map_variances(self) -> np.ndarray:
        """Every copy's terrain map cell variances (N, G) [m^2] (a copy)."""
        return self._map_variances.copy()

    @property
    def elapsed_steps(self) -> np.ndarray:
        """Every copy's steps since its reset (N,) (a copy)."""
        return self._elapsed.copy()

    @property
    def decision(self) -> ExplorationDecision:
        """The current decision of every copy (masks, expected gains, the observation slots' validity)."""
        return self._decision

    def copy_state(self, copy: int) -> CopyState:
        """Copy ``copy``'s estimator state at its current decision.

        Raises:
            RuntimeError: before the first ``reset()``.
        """
        if self._decision is None:
            raise RuntimeError(f"{self.owner_name}: call reset() before copy_state() (a planning model's belief())")
        done = self._lost[copy].any() or self._success[copy] or self._elapsed[copy] >= self.max_cycles
        return CopyState(
            self._x[copy].copy(),
            self._P[copy].copy(),
            self._map_variances[copy].copy(),
            self._observations_left[copy].copy(),
            bool(done),
        )

    def planning_model(self, copy: int = 0) -> ExplorationPlanningModel:
        """The planning model of copy ``copy`` (the same object on every call), for look-ahead agents
        (``agents.planner.PlannerAgent``)."""
        if copy not in self._planning_models:
            self._planning_models[copy] = ExplorationPlanningModel(self, copy)
        return self._planning_models[copy]

    # ------------------------------------------------------------------ reset

    def _reset_copies(self, copies: np.ndarray) -> None:
        """Start a new episode in each of ``copies`` from its own generator."""
        for copy in copies.tolist():
            scenario, poses, covariances, *generators = start_episode(self.config, self._np_randoms[copy])
            self._start_copy(copy, scenario, poses, covariances, generators)
            self._landmarks[copy] = scenario.landmarks
            self._geometries[copy] = StaticGeometry.from_scenario(scenario, self._worlds.wall_thickness_m)
        geometry = StaticGeometry.stack([self._geometries[copy] for copy in copies.tolist()])
        self._geometry = geometry if len(copies) == self.num_envs else self._geometry.with_copies(copies, geometry)
        self._map_variances[copies] = self.parts.map_model.prior_variances()
        self._coverage[copies] = 0.0
        self._observations_left[copies] = self.config["max_observations"]
        self._lost[copies] = self._success[copies] = False
        self._started(copies)
        if copies[0] == 0 and self.render_mode is not None:
            self._paths = FirstCopyPaths(self._worlds.poses[0], self._x[0].reshape(-1, POSE_DIM))
            self._observed_pairs, self._observed_landmarks = [], []

    def _reset_record(self) -> ExplorationStep:
        return ExplorationStep.nothing(self.num_envs, len(self.agents), REWARD_TERMS)

    def _restarted(self, record: ExplorationStep, copies: np.ndarray) -> ExplorationStep:
        return record.restarted(copies)

    # ------------------------------------------------------------------ step

    def _act(self, chosen: np.ndarray, invalid: np.ndarray, acting: np.ndarray) -> tuple:
        """Observe at the prior, drive, predict, fuse DGPS, then scan, in the ``acting`` copies (rewards: see
        ``CooperativeExplorationEnv``)."""
        cfg, decision = self.config, self._decision
        record = ExplorationStep.nothing(self.num_envs, len(self.agents), REWARD_TERMS)._replace(
            stepped=acting, chosen=chosen, invalid=invalid
        )
        copies = np.flatnonzero(acting)
        if not copies.size:
            return record, np.zeros(chosen.shape), np.zeros(self.num_envs, dtype=bool)
        rows, n_landmarks = self._rows(copies), cfg["n_landmarks"]
        slots, motions = np.divmod(chosen[rows], N_MOTIONS)
        plan = motion_plan(motions, self._x[rows, 2::POSE_DIM], self.parts.speeds_mps)  # the decision's, as masked
        if acting[0] and self.render_mode is not None:  # drawn by render()
            self._first_copy_observed(slots[0])
        observes_teammate = slots > n_landmarks
        teammates = np.where(observes_teammate, slots - n_landmarks, 0)
        self._relative_update(copies, teammates, decision.team)
        self._observe_landmarks(copies, np.where((slots > 0) & ~observes_teammate, slots - 1, -1))
        observed = slots > 0
        self._observations_left[copies] -= observed
        n_robots = len(self.agents)
        own_information = 0.5 * (
            decision.team.pose_log_det[rows] - batched.pose_log_dets(self._P[rows], n_robots, check_input=False)
        )
        self._drive(copies, *plan)
        self._elapsed[copies] += 1
        self._gps_fixes(copies)
        position_std = ExplorationPlanningModel.position_std(self._P[rows])
        map_information = self._scan(copies, motions != STAY, position_std)
        lost = position_std > cfg["max_position_std_m"]
        self._lost[copies] = lost
        self._success[copies] = (self._coverage[copies] >= cfg["coverage_target"]) & ~lost.any(axis=1)
        terms = reward_terms(cfg, own_information, map_information, observed, motions != STAY, lost.any(axis=1))
        for key, value in terms.items():
            record.terms[key][copies] = value
        rewards = np.zeros(chosen.shape)
        rewards[copies] = total_reward(cfg["team_reward"], terms)
        terminated = np.zeros(self.num_envs, dtype=bool)
        terminated[copies] = lost.any(axis=1) | self._success[copies]
        if acting[0] and self._paths is not None:
            self._paths.extend(self._worlds.poses[0], self._x[0].reshape(-1, POSE_DIM))
        return record, rewards, terminated

    def _first_copy_observed(self, slots: np.ndarray) -> None:
        """Keep copy 0's teammate and landmark observations of this step (its robots' observation ``slots`` (R,))."""
        n_landmarks, robots = self.config["n_landmarks"], np.arange(len(slots))
        teammates = slots > n_landmarks
        landmarks = (slots > 0) & ~teammates
        self._observed_pairs = list(zip(robots[teammates].tolist(), (slots[teammates] - 1 - n_landmarks).tolist()))
        self._observed_landmarks = list(zip(robots[landmarks].tolist(), (slots[landmarks] - 1).tolist()))

    def _observe_landmarks(self, copies: np.ndarray, landmarks: np.ndarray) -> None:
        """Fuse the observations of landmark ``landmarks[c, k]`` (-1: none) by robot k of ``copies[c]``, linearized at
        the estimate, as one stacked update per copy."""
        observed = landmarks >= 0
        rows = np.flatnonzero(observed.any(axis=1))
        if not rows.size:
            return
        observers, observed, choice = copies[rows], observed[rows], np.maximum(landmarks[rows], 0)
        positions = self._landmarks[observers[:, None], choice]  # (n, R, 2)
        poses = self._x[observers].reshape(-1, POSE_DIM)
        predicted, H = batched.landmark_measurement_model(poses, positions.reshape(-1, 1, 2), check_input=False)
        predicted = predicted.reshape(*observed.shape, 2)
        robots = np.broadcast_to(np.arange(observed.shape[1]), observed.shape)
        R = range_bearing_noise(self._sight.noise_stds, robots.ravel(), predicted[..., 0].ravel())
        R = R.reshape(*observed.shape, 2, 2)
        noise = self._noise[LANDMARK_NOISE].take_many(observers, observed)
        measurements = self._sight.landmark_measurements(self._worlds.poses[observers], positions, noise)
        self._x[observers], self._P[observers] = batched.team_landmark_update(
            self._x[observers],
            self._P[observers],
            robots,
            measurements,
            predicted,
            H.reshape(*observed.shape, 2, POSE_DIM),
            R,
            observed,
            check_input=False,
        )

    def _drive(self, copies: np.ndarray, turns: np.ndarray, speeds: np.ndarray) -> None:
        """Turn every robot of ``copies`` on the spot by ``turns`` (n, R) [rad], then drive it straight at ``speeds``
        (n, R) [m/s] (both in the ``WorldBatch``); predict with the odometry of each phase."""
        cfg = self.config
        turn_s = cfg["turn_time_s"]
        turning = np.stack([np.zeros_like(turns), turns / turn_s], axis=-1)
        driving = np.stack([speeds, np.zeros_like(turns)], axis=-1)
        for phase_s, commands in ((turn_s, turning), (cfg["time_step_s"] - turn_s, driving)):
            self._predict(copies, self._worlds.step(phase_s, copies, commands), phase_s)

    def _scan(self, copies: np.ndarray, scanning: np.ndarray, position_std: np.ndarray) -> np.ndarray:
        """Fuse the scans of the ``scanning`` robots (n, R) of ``copies`` from their true positions; the map
        information of each copy (n,) [nats]."""
        information = np.zeros(len(copies))
        rows = np.flatnonzero(scanning.any(axis=1))
        if not rows.size:
            return information
        model, mapped = self.parts.map_model, self._rows(copies[rows])
        noise = model.scan_noise_variances(position_std[rows])
        after, information[rows] = model.fused(
            self._map_variances[mapped], self._worlds.poses[mapped, :, :2], noise, scanning[rows]
        )
        self._map_variances[mapped] = after
        self._coverage[mapped] = model.coverage(after)
        return information

    # ------------------------------------------------------------------ decision and outputs

    def _decide(self) -> None:
        """Masks and immediate expected gains of every (observation, motion) pair of every copy, at its prior."""
        cfg, sight = self.config, self._sight
        true_poses, x, P = self._worlds.poses, self._x, self._P
        n_copies, n_robots = true_poses.shape[:2]
        budget_left = self._observations_left > 0
        pair_geometry, valid = observable_pairs(self._pairs, self._geometry, true_poses)
        valid &= budget_left[:, self._pairs.observers]
        team = TeamDecision.at_prior(self._pairs, pair_geometry, valid, x, P, 0.0)  # the gains: own-pose MI
        landmark_valid = sight.visible_landmarks(self._geometry, true_poses, self._landmarks) & budget_left[..., None]
        gains_of_landmarks = landmark_gains(x, P, self._landmarks, sight.noise_stds, landmark_valid)
        slot_valid = np.concatenate(
            [np.ones((n_copies, n_robots, 1), dtype=bool), landmark_valid, team.action_mask[..., 1:].astype(bool)],
            axis=-1,
        )
        observation_gain = np.concatenate(
            [np.zeros((n_copies, n_robots, 1)), gains_of_landmarks, team.action_information_gain[..., 1:]], axis=-1
        )
        position_std = ExplorationPlanningModel.position_std(P)
        drive_s = cfg["time_step_s"] - cfg["turn_time_s"]
        positions = x.reshape(n_copies, n_robots, POSE_DIM)[..., :2]
        speeds, radius_m = self.parts.speeds_mps, self._worlds.robot_radius_m
        scan = scan_gains(self.parts.map_model, self._map_variances, positions, position_std, speeds, drive_s)
        clear = clear_motions(self._geometry, true_poses, x[:, 2::POSE_DIM], speeds, drive_s, radius_m)
        mask = slot_valid[..., None] & clear[:, :, None, :]
        gains = action_gains(cfg["team_reward"], observation_gain, scan, mask).reshape(n_copies, n_robots, -1)
        mask = mask.reshape(n_copies, n_robots, -1).astype(np.int8)
        self._decision = ExplorationDecision(mask, gains, team, slot_valid, position_std)

    def _outputs(self, last: ExplorationStep) -> tuple[np.ndarray, dict]:
        """The observations and infos of every copy at the current decision, after ``last``."""
        decision, cfg = self._decision, self.config
        n_copies, n_robots = self._gps_available.shape
        n_landmarks, budget = cfg["n_landmarks"], cfg["max_observations"]
        estimates = self._x.reshape(n_copies, n_robots, POSE_DIM)
        team = team_observations(
            estimates,
            decision.team.pose_std,
            decision.team.pose_log_det,
            self._gps_available,
            self._elapsed / self.max_cycles,
            decision.slot_valid[..., 1 + n_landmarks :],
            self._team_space,
        )
        seen = range_bearing(estimates.reshape(-1, POSE_DIM), np.repeat(self._landmarks, n_robots, axis=0))
        observations = exploration_observations(
            team,
            decision.slot_valid[..., 1 : 1 + n_landmarks],
            seen.reshape(n_copies, n_robots, n_landmarks, 2),
            self.parts.speeds_mps,
            self._observations_left / budget if budget else np.zeros((n_copies, n_robots)),
            self._coverage,
            np.sqrt(self._map_variances) / self.parts.map_model.prior_std_m,
            self.single_observation_space,
            decision.action_information_gain if cfg["observe_gains"] else None,
        )
        state = {
            "x": self._x,
            "true_poses": self._worlds.poses,
            "gps_available": self._gps_available,
            "observations_left": self._observations_left,
            "lost": self._lost,
            "coverage": self._coverage,
            "success": self._success,
            "time_s": self._elapsed * cfg["time_step_s"],
        }
        return observations, exploration_info(decision, last, state)

    # ------------------------------------------------------------------ rendering

    def _scene_frame(self) -> SceneFrame:
        """Copy 0 drawn: its field, the terrain map (inset), every robot (truth, estimate, covariance, paths) and this
        step's teammate and landmark observations."""
        scenario, side = self._worlds.scenario(0), self.config["map_cells_per_side"]
        known = 1.0 - np.sqrt(self._map_variances[0]) / self.parts.map_model.prior_std_m
        image = np.kron(np.flipud(known.reshape(side, side)), np.ones((MAP_IMAGE_PIXELS_PER_CELL,) * 2))
        time_s = self._elapsed[0] * self.config["time_step_s"]
        pairs, landmarks = self._observed_pairs, self._observed_landmarks
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            landmarks=scenario.landmarks,
            robots=self._paths.drawings(
                self._worlds.poses[0], self._x[0], self._P[0], self.agents, self._gps_available[0]
            ),
            observations=list(pairs),
            landmark_observations=list(landmarks),
            gps_denied_zones=scenario.gps_denied_zones,
            inset_image=np.round(255 * image).astype(np.uint8),
            inset_title=f"terrain map (white: known), coverage {self._coverage[0]:.0%}",
            caption=f"t = {time_s:.0f} s   {len(pairs)} teammate and {len(landmarks)} landmark observations this step",
        )
