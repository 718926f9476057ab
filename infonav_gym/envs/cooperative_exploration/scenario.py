"""``cooperative_exploration_v0`` as a scenario: a team maps a field, each robot choosing where to go and what to see;
``CooperativeExplorationVectorEnv`` is its driver, ``CooperativeExplorationEnv`` its PettingZoo view."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from infonav_gym.envs.cooperative_exploration.exploration_decision import (
    ExplorationDecision,
    TeamSight,
    landmark_gains,
    range_bearing_noise,
)
from infonav_gym.envs.cooperative_exploration.exploration_planning import (
    N_MOTIONS,
    NOOP_ACTION,
    STAY,
    ExplorationPlanningModel,
    action_table,
    clear_motions,
    motion_phases,
    motion_plan,
    reward_terms,
    scan_gains,
    total_reward,
)
from infonav_gym.envs.cooperative_exploration.exploration_team import (
    CONFIG_INTERVALS,
    REWARD_TERMS,
    ExplorationParts,
    exploration_config,
    exploration_observation_bounds,
    exploration_observations,
    start_episode,
)
from infonav_gym.envs.driver import Driver
from infonav_gym.envs.metrics import EXPLORATION_METRICS
from infonav_gym.envs.parallel_view import ParallelEnvView, team_metadata
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.estimation import batched
from infonav_gym.estimation.models import range_bearing
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.multi.team_decision import TeamDecision, observable_pairs
from infonav_gym.multi.team_observations import team_observation_bounds, team_observations
from infonav_gym.multi.team_scenario import TeamAccessors, TeamScenario, TeamState, copy_rows
from infonav_gym.scene import SceneFrame

LANDMARK_NOISE = 3  # ``noise`` index of the landmark measurements' streams (after odometry, DGPS, relative poses)
MAP_IMAGE_PIXELS_PER_CELL = 8
MAP_CELL_KB = 0.07  # [kB] a copy's memory per coverage-map cell, measured from 20 x 20 to 100 x 100 cells


@dataclass
class ExplorationState(TeamState):
    """``TeamState`` and each copy's landmarks (N, L, 2), terrain map cell variances (N, G) [m^2], coverage (N,),
    sensing budgets (N, R), which robots are lost (N, R), whether it succeeded (N,); what its last step brought: each
    robot's own pose MI (N, R) and the map information (N,) [nats], whether it observed and drove (N, R); and copy
    0's observed landmarks (robot, landmark)."""

    landmarks: np.ndarray = None
    map_variances: np.ndarray = None
    coverage: np.ndarray = None
    observations_left: np.ndarray = None
    lost: np.ndarray = None
    success: np.ndarray = None
    own_information: np.ndarray = None
    map_information: np.ndarray = None
    observed: np.ndarray = None
    driving: np.ndarray = None
    observed_landmarks: list = None


class CooperativeExploration(TeamScenario):
    """``cooperative_exploration_v0`` as a scenario: see ``CooperativeExplorationEnv`` for its spaces, rewards and
    config keys."""

    metadata = team_metadata("cooperative_exploration_v0")
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
        info_keys=frozenset(
            {"gps_available", "pose_std", "position_std_m", "pose_entropy", "position_error_m", "heading_error_rad"}
            | {"estimated_pose", "observations_left", "coverage", "lost", "failed", "success"}
        ),
    )
    team_info_keys = frozenset({"time_s", "coverage", "failed", "success"})

    @classmethod
    def default_config(cls) -> dict:
        return exploration_config()

    @classmethod
    def copy_kb(cls, config: dict) -> float:
        """``kb_per_copy`` and ``MAP_CELL_KB`` a map cell beyond the default's."""
        side = min(config["map_cells_per_side"], CONFIG_INTERVALS["map_cells_per_side"].high)
        more_cells = side**2 - cls.default_config()["map_cells_per_side"] ** 2
        return cls.traits.kb_per_copy + MAP_CELL_KB * max(more_cells, 0)

    def __init__(self, config: dict, copies: int, owner: str, render_mode: str | None):
        super().__init__(config, copies, owner, render_mode)
        self.parts = parts = ExplorationParts.of_config(config, owner)
        n_robots, n_landmarks = len(parts.gps), config["n_landmarks"]
        team_low, team_high = team_observation_bounds(n_robots, False)
        self.team_space = spaces.Box(team_low, team_high, dtype=np.float32)
        self.action_space = spaces.Discrete(N_MOTIONS * (1 + n_landmarks + n_robots))
        n_gains = self.action_space.n if config["observe_gains"] else 0
        low, high = exploration_observation_bounds(team_low, team_high, n_landmarks, parts.map_model.n_cells, n_gains)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.use_team(parts.pairs, parts.gps, parts.odometry)
        self.sight = TeamSight(tuple(parts.relative_sensors))

    def allocate(self, copies: int) -> ExplorationState:
        shape = (copies, len(self.agents))
        return ExplorationState(
            **self.team_fields(copies, (2,)),
            landmarks=np.zeros((copies, self.config["n_landmarks"], 2)),
            map_variances=np.zeros((copies, self.parts.map_model.n_cells)),
            coverage=np.zeros(copies),
            observations_left=np.zeros(shape, dtype=int),
            lost=np.zeros(shape, dtype=bool),
            success=np.zeros(copies, dtype=bool),
            **self.no_step(copies),
            observed_landmarks=[],
        )

    def no_step(self, copies: int) -> dict:
        """What ``copies`` copies that did not step brought: nothing."""
        shape = (copies, len(self.agents))
        return {
            "own_information": np.zeros(shape),
            "map_information": np.zeros(copies),
            "observed": np.zeros(shape, dtype=bool),
            "driving": np.zeros(shape, dtype=bool),
        }

    def initial(self, state: ExplorationState, rows: np.ndarray, rngs: list) -> ExplorationState:
        """Draw each copy's field, landmarks and joint prior (``start_episode``), then its first DGPS fixes."""
        for copy, rng in zip(rows.tolist(), rngs):
            state.landmarks[copy] = self.start_copy(state, copy, *start_episode(self.config, rng)).landmarks
        state.map_variances[rows] = self.parts.map_model.prior_variances()
        state.coverage[rows] = 0.0
        state.observations_left[rows] = self.config["max_observations"]
        state.lost[rows] = state.success[rows] = False
        self.started(state, rows)
        if rows[0] == 0:
            state.observed_landmarks = []
        return state

    def decision(self, state: ExplorationState, rows) -> ExplorationDecision:
        """Masks and immediate expected gains of every (observation, motion) pair of the copies ``rows``, at their
        priors."""
        cfg, sight = self.config, self.sight
        geometry = self.rows_geometry(state, rows)
        true_poses, x, P, landmarks = state.worlds.poses[rows], state.x[rows], state.P[rows], state.landmarks[rows]
        n_copies, n_robots = true_poses.shape[:2]
        budget_left = state.observations_left[rows] > 0
        pair_geometry, valid = observable_pairs(self.pairs, geometry, true_poses)
        valid &= budget_left[:, self.pairs.observers]
        team = TeamDecision.at_prior(self.pairs, pair_geometry, valid, x, P, 0.0)  # the gains: own-pose MI
        landmark_valid = sight.visible_landmarks(geometry, true_poses, landmarks) & budget_left[..., None]
        gains_of_landmarks = landmark_gains(x, P, landmarks, sight.noise_stds, landmark_valid)
        team_valid, team_gain = team.action_mask > 0, team.action_information_gain  # slot 0: observe nothing, gain 0
        slot_valid = np.concatenate([team_valid[..., :1], landmark_valid, team_valid[..., 1:]], axis=-1)
        observation_gain = np.concatenate([team_gain[..., :1], gains_of_landmarks, team_gain[..., 1:]], axis=-1)
        position_std = ExplorationPlanningModel.position_std(P)
        drive_s = cfg["time_step_s"] - cfg["turn_time_s"]
        positions = x.reshape(n_copies, n_robots, POSE_DIM)[..., :2]
        speeds, radius_m = self.parts.speeds_mps, state.worlds.robot_radius_m
        scan = scan_gains(self.parts.map_model, state.map_variances[rows], positions, position_std, speeds, drive_s)
        clear = clear_motions(geometry, true_poses, x[:, 2::POSE_DIM], speeds, drive_s, radius_m)
        mask, gains = action_table(cfg["team_reward"], slot_valid, observation_gain, clear, scan)
        return ExplorationDecision(mask, gains, *team[2:], slot_valid, position_std)

    def transition(self, state: ExplorationState, decision: ExplorationDecision, action, acting) -> ExplorationState:
        """Observe at the prior, drive, predict, fuse DGPS, then scan, in the ``acting`` copies."""
        cfg = self.config
        state.chosen, state.invalid = np.where(action >= 0, action, NOOP_ACTION), acting[:, None] & (action < 0)
        for key, value in self.no_step(len(acting)).items():
            setattr(state, key, value)
        copies = np.flatnonzero(acting)
        if not copies.size:
            return state
        rows, n_landmarks = copy_rows(copies, len(acting)), cfg["n_landmarks"]
        slots, motions = np.divmod(state.chosen[rows], N_MOTIONS)
        plan = motion_plan(motions, state.x[rows, 2::POSE_DIM], self.parts.speeds_mps)  # the decision's, as masked
        observes_teammate = slots > n_landmarks
        teammates = np.where(observes_teammate, slots - n_landmarks, 0)
        landmarks = np.where((slots > 0) & ~observes_teammate, slots - 1, -1)
        if acting[0] and self.drawing:  # drawn by ``frame``: copy 0's (robot, teammate) and (robot, landmark) pairs
            state.observed_pairs = [(robot, int(j) - 1) for robot, j in enumerate(teammates[0]) if j]
            state.observed_landmarks = [(robot, int(j)) for robot, j in enumerate(landmarks[0]) if j >= 0]
        self.relative_update(state, copies, teammates, decision)
        self.observe_landmarks(state, copies, landmarks)
        observed = slots > 0
        state.observations_left[copies] -= observed
        own_information = 0.5 * (
            decision.pose_log_det[rows] - batched.pose_log_dets(state.P[rows], len(self.agents), check_input=False)
        )
        for phase_s, commands in motion_phases(*plan, cfg):  # turn on the spot, then drive straight
            self.predict(state, copies, state.worlds.step(phase_s, copies, commands), phase_s)
        self.gps_fixes(state, copies, state.elapsed[copies] + 1)  # the driver counts the step after
        position_std = ExplorationPlanningModel.position_std(state.P[rows])
        driving = motions != STAY
        map_information = self.scan(state, copies, driving, position_std)
        lost = position_std > cfg["max_position_std_m"]
        state.lost[copies] = lost
        state.success[copies] = (state.coverage[copies] >= cfg["coverage_target"]) & ~lost.any(axis=1)
        state.own_information[copies], state.map_information[copies] = own_information, map_information
        state.observed[copies], state.driving[copies] = observed, driving
        self.moved(state, copies)
        return state

    def step_terms(self, state: ExplorationState, rows) -> dict:
        """The reward terms (``reward_terms``) of the last step of the copies ``rows`` (n, R)."""
        brought = (state.own_information, state.map_information, state.observed, state.driving)
        return reward_terms(self.config, *(array[rows] for array in brought), state.lost[rows].any(axis=1))

    def reward(self, decision, action, state: ExplorationState) -> np.ndarray:
        """Each robot's reward of its terms (``total_reward``, as the planning model's)."""
        return total_reward(self.config["team_reward"], self.step_terms(state, slice(None)))

    def terminal(self, state: ExplorationState) -> np.ndarray:
        """A robot lost, or the coverage target reached."""
        return state.lost.any(axis=1) | state.success

    def observe_landmarks(self, state: ExplorationState, copies: np.ndarray, landmarks: np.ndarray) -> None:
        """Fuse the observations of landmark ``landmarks[c, k]`` (-1: none) by robot k of ``copies[c]``, linearized at
        the estimate, as one stacked update per copy."""
        observed = landmarks >= 0
        rows = np.flatnonzero(observed.any(axis=1))
        if not rows.size:
            return
        observers, observed, choice = copies[rows], observed[rows], np.maximum(landmarks[rows], 0)
        positions = state.landmarks[observers[:, None], choice]  # (n, R, 2)
        x, P = state.x[observers], state.P[observers]
        predicted, H = batched.landmark_measurement_model(
            x.reshape(-1, POSE_DIM), positions.reshape(-1, 1, 2), check_input=False
        )
        predicted, H = predicted.reshape(*observed.shape, 2), H.reshape(*observed.shape, 2, POSE_DIM)
        robots = np.broadcast_to(np.arange(observed.shape[1]), observed.shape)
        R = range_bearing_noise(self.sight.noise_stds, robots.ravel(), predicted[..., 0].ravel())
        R = R.reshape(*observed.shape, 2, 2)
        noise = state.noise[LANDMARK_NOISE].take_many(observers, observed)
        measurements = self.sight.landmark_measurements(state.worlds.poses[observers], positions, noise)
        state.x[observers], state.P[observers] = batched.team_landmark_update(
            x, P, robots, measurements, predicted, H, R, observed, check_input=False
        )

    def scan(self, state: ExplorationState, copies: np.ndarray, scanning: np.ndarray, position_std) -> np.ndarray:
        """Fuse the scans of the ``scanning`` robots (n, R) of ``copies`` from their true positions; the map
        information of each copy (n,) [nats]."""
        information, rows = np.zeros(len(copies)), np.flatnonzero(scanning.any(axis=1))
        model, mapped = self.parts.map_model, copy_rows(copies[rows], len(state.elapsed))
        noise = model.scan_noise_variances(position_std[rows])
        after, information[rows] = model.fused(
            state.map_variances[mapped], state.worlds.poses[mapped, :, :2], noise, scanning[rows]
        )
        state.map_variances[mapped] = after
        state.coverage[mapped] = model.coverage(after)
        return information

    def observation(self, state: ExplorationState, decision: ExplorationDecision, rows) -> np.ndarray:
        cfg = self.config
        n_landmarks, budget = cfg["n_landmarks"], cfg["max_observations"]
        n_copies, n_robots = state.gps_available[rows].shape
        estimates = state.x[rows].reshape(n_copies, n_robots, POSE_DIM)
        teammate_valid = decision.slot_valid[..., 1 + n_landmarks :]
        team = team_observations(state, decision, rows, cfg["max_cycles"], teammate_valid, self.team_space)
        seen = range_bearing(estimates.reshape(-1, POSE_DIM), np.repeat(state.landmarks[rows], n_robots, axis=0))
        return exploration_observations(
            team,
            decision.slot_valid[..., 1 : 1 + n_landmarks],
            seen.reshape(n_copies, n_robots, n_landmarks, 2),
            self.parts.speeds_mps,
            state.observations_left[rows] / budget if budget else np.zeros((n_copies, n_robots)),
            state.coverage[rows],
            np.sqrt(state.map_variances[rows]) / self.parts.map_model.prior_std_m,
            self.observation_space,
            decision.action_information_gain if cfg["observe_gains"] else None,
        )

    def info(self, state: ExplorationState, decision: ExplorationDecision, rows, stepped) -> dict:
        """The decision's masks and gains, the reward terms, the actions, the estimates, map and budgets."""
        lost = state.lost[rows]
        return self.team_info(
            state,
            decision,
            rows,
            stepped,
            self.step_terms(state, rows),
            position_std_m=decision.position_std.copy(),
            observations_left=state.observations_left[rows].copy(),
            coverage=state.coverage[rows].copy(),
            lost=lost.copy(),
            failed=lost.any(axis=1),
            success=state.success[rows].copy(),
        )

    def frame(self, state: ExplorationState, decision: ExplorationDecision) -> SceneFrame:
        """Copy 0 drawn: its field, the terrain map (inset), every robot (truth, estimate, covariance, paths) and this
        step's teammate and landmark observations."""
        side = self.config["map_cells_per_side"]
        known = 1.0 - np.sqrt(state.map_variances[0]) / self.parts.map_model.prior_std_m
        image = np.kron(np.flipud(known.reshape(side, side)), np.ones((MAP_IMAGE_PIXELS_PER_CELL,) * 2))
        time_s = state.elapsed[0] * self.config["time_step_s"]
        pairs, landmarks = state.observed_pairs, state.observed_landmarks
        return self.team_frame(
            state,
            f"t = {time_s:.0f} s   {len(pairs)} teammate and {len(landmarks)} landmark observations this step",
            landmarks=state.worlds.scenario(0).landmarks,
            observations=list(pairs),
            landmark_observations=list(landmarks),
            inset_image=np.round(255 * image).astype(np.uint8),
            inset_title=f"terrain map (white: known), coverage {state.coverage[0]:.0%}",
        )


class CooperativeExplorationVectorEnv(TeamAccessors, Driver, scenario=CooperativeExploration):
    """N copies of ``cooperative_exploration_v0`` (the driver's vector API, autoreset and arguments; spaces,
    rewards and config keys: ``CooperativeExplorationEnv``).

    Observations (N, R, 10 + 5R + 4L + 3 + G; A more with ``observe_gains``); rewards, ``terminated``, ``truncated``
    (N, R); infos (N, R, ...) (the team's ``time_s``, ``coverage``, ``failed``, ``success``: (N,));
    ``info["action_mask"]`` and ``action_masks()`` (N, R, 5 (1 + L + R)). ``planning_model(copy)``: copy
    ``copy``'s planning model (``exploration_planning``).
    """

    @property
    def parts(self) -> ExplorationParts:
        """The team's sensors, speeds and map model (``ExplorationParts``), as the config gives them."""
        return self.env_scenario.parts

    @property
    def map_variances(self) -> np.ndarray:
        """Every copy's terrain map cell variances (N, G) [m^2] (a copy)."""
        return self.state.map_variances.copy()

    def planning_model(self, copy: int = 0) -> ExplorationPlanningModel:
        """The planning model of copy ``copy`` (the same object on every call), for look-ahead agents
        (``agents.planner.PlannerAgent``)."""
        models = vars(self).setdefault("_planning_models", {})  # made by the first call
        if copy not in models:
            models[copy] = ExplorationPlanningModel(self, copy)
        return models[copy]


class CooperativeExplorationEnv(ParallelEnvView, vector_env=CooperativeExplorationVectorEnv):
    """A heterogeneous team maps a field; each robot chooses where to drive and what to observe, together.

    ## Description
    The paper's Section III-C, distributed heterogeneous multirobot exploration. The team starts at a base in one
    corner of a square Pymunk field (``exploration_field``) with round obstacles, GPS-denied canopy zones and a few
    landmarks, and must map the terrain: a grid of cells whose heights are Gaussian estimates (``terrain_map``). A
    robot that drives scans the cells around it; a position error ``sigma`` puts heights at the wrong place, so a
    scan's height noise grows as ``scan_std_m^2 + (terrain_slope * sigma)^2``: a badly localized robot maps poorly.
    A joint EKF over all poses fuses odometry, DGPS fixes (robots with DGPS, outside the canopies) and the
    observations the agents choose: a known landmark (range-bearing) or a teammate (relative pose, which correlates
    the two).

    Why a myopic agent fails: the robots without DGPS drift on odometry alone and stay localized only while a
    landmark or a well-localized teammate is within their sensor's short range. The unmapped cells lie far from
    both, so the action with the most immediate information (drive to fresh cells, observe whatever is in sight)
    leads the GPS-less robots away from every reference; their position std then crosses ``max_position_std_m`` and
    the team fails. Succeeding needs plans over several steps: scouts that cover far cells while returning near a
    teammate or a landmark in time, DGPS robots that escort them and leave the canopies, and a budget kept for when
    it matters.

    ## Agents
    ``robot_0 .. robot_{N-1}`` (default 4). Suites from ``robot_sensors`` (default: suite ``k % 4`` of ``gps+laser,
    gps+laser, laser, vision``; odometry always), speeds from ``robot_speeds_mps`` (default ``0.8, 0.8, 1.2, 1.2``
    m/s: the DGPS robots are slower). The laser sees all around up to ``laser_range_m``, the camera a 60 deg field
    of view up to ``vision_range_m``; a robot observes landmarks and teammates with its one sensor.

    ## Action Space
    ``Discrete(5 * (1 + L + N))`` per agent, ``L = n_landmarks``: action ``a`` is slot ``a // 5`` and motion ``a %
    5``. Slots: 0 observe nothing, ``1 + j`` landmark ``j``, ``1 + L + j`` ``robot_j``. A motion (``stay``,
    ``east``, ``north``, ``west``, ``south``) turns the robot on the spot for ``turn_time_s`` until its heading
    *estimated at the decision* is the compass heading, then drives it straight at its speed for the rest of the
    step (``stay`` does neither); Pymunk executes both phases, and both are exact unicycle motions for the EKF. A
    motion is valid while its true path keeps ``clearance.CLEARANCE_M`` (5 cm) from walls, obstacles and wherever a
    teammate's motions can take it (``world.clearance``): no contact ever pushes a robot unseen by its odometry. An
    observation is valid while the target is in range and field of view with a clear line of sight and the robot has
    budget left (``max_observations``); every observation goes with every valid motion, and action 0 (stay, observe
    nothing) is always valid. A masked action is action 0 (``invalid_action="noop"``) or raises ``ValueError``
    (``"raise"``).

    ## Observation Space
    ``Box(float32, (10 + 5 N + 4 L + 3 + G,))``, ``G = map_cells_per_side^2``: the 10 own and 5 per-robot features
    of ``cooperative_localization_v0``; per landmark: whether observing it is valid, its estimated range [m], ``cos,
    sin`` of its estimated bearing; the robot's speed [m/s], its budget left (fraction), the team's coverage; per
    cell (row-major from the lower left corner) the height std left, as a fraction of ``map_prior_std_m``. With
    ``observe_gains=True`` (off by default), ``5 (1 + L + N)`` more: ``action_information_gain`` of each action, the
    immediate expected gains the greedy agent ranks and the planner starts its search from.

    ## Rewards
    ``(1 - team_reward) * own_pose_information + team_reward * team_map_information`` plus the costs, with the
    terms at ``info["reward_" + term]``: ``own_pose_information``, the realized MI of the step's observations on the
    robot's own pose [nats]; ``team_map_information``, the map entropy reduction of every robot's scans this step
    [nats]; ``sensing_cost`` ``-observation_cost_nats`` per observation; ``motion_cost`` ``-motion_cost_per_step``
    per step driven; ``lost_penalty`` ``-lost_penalty`` for every robot when one is lost.
    ``info["action_information_gain"][a]`` is the immediate expected information of ``a``: ``(1 - team_reward)``
    times the MI its observation alone brings to the robot's pose at the prior, plus ``team_reward`` times the map
    information its scan alone would bring, from the position the motion predicts, at the robot's current position
    std (0 where masked). A scan is taken only after driving forward: standing or turning in place sees the same
    view again, with the same errors, so it brings nothing new (action 0 has gain 0).

    ## Info
    ``infos[agent]``: ``action_mask`` (int8), ``action_information_gain``, ``reward_<term>``, ``chosen_action``,
    ``invalid_action``, ``gps_available``, ``pose_std``, ``position_std_m`` (largest, at the decision),
    ``pose_entropy``, ``position_error_m``, ``heading_error_rad``, ``true_pose``, ``estimated_pose``, ``time_s``,
    ``observations_left``, ``coverage`` (team), ``lost`` (this robot), ``failed`` and ``success`` (the team).

    ## Starting State
    Parked at the base, facing the field's centre; estimates drawn from ``N(true pose,
    diag(initial_position_std_m^2, ..., initial_heading_std_rad^2))``; the map at its prior (std ``map_prior_std_m``
    in every cell).

    ## Episode End
    Terminated for all agents when a robot's largest position std exceeds ``max_position_std_m`` (it is lost:
    ``failed``), or when the coverage reaches ``coverage_target`` (``success``); truncated after ``max_cycles``
    steps (no success).

    ## Planning model
    ``planning_model()`` is the model look-ahead agents search (``ExplorationPlanningModel``,
    ``agents.planner.PlannerAgent(env, robot)``): ``belief()`` copies the joint EKF state, the map and the budgets,
    ``plan_decision(belief, robot)`` and ``plan_step(belief, team_actions)`` step them under the expected
    measurements with the env's own functions, never reading the true state.

    ## Arguments
    ``parallel_env(render_mode=None, **config)`` with any key of ``default_config()``; an unknown key or a bad value
    raises ``ValueError`` naming it. The env is the N = 1 view of ``CooperativeExplorationVectorEnv`` (its one
    implementation, ``self.vector``: ``scenario(0)``, ``true_poses``, ``joint_state()``, ``map_variances``).

    ## Version History
    * v0: initial version (issue 18). Motions masked clear of contacts, and the planning model, added before any
      results were committed; the N = 1 view of the vector env since the one-implementation refactor (same numbers).
    """
