"""``cooperative_localization_v0`` as a scenario: a heterogeneous team localizes through relative-pose observations;
``CooperativeLocalizationVectorEnv`` is its driver, ``CooperativeLocalizationEnv`` its PettingZoo view."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from infonav_gym.envs.cooperative_localization.team_localization import (
    TeamParts,
    start_episode,
    team_localization_config,
)
from infonav_gym.envs.driver import Driver
from infonav_gym.envs.metrics import TEAM_LOCALIZATION_METRICS
from infonav_gym.envs.parallel_view import ParallelEnvView, team_metadata
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.multi.team_decision import TeamDecision, observable_pairs
from infonav_gym.multi.team_observations import team_observation_bounds, team_observations
from infonav_gym.multi.team_scenario import TeamAccessors, TeamScenario, TeamState
from infonav_gym.multi.team_sensing import NO_OBSERVATION
from infonav_gym.scene import SceneFrame


@dataclass
class LocalizationState(TeamState):
    """``TeamState`` and what each copy's last step brought: each robot's MI on its own pose and the team's (N, R)
    [nats] and its standard deviations right after the relative updates (N, R, 3)."""

    own_mi: np.ndarray = None
    team_mi: np.ndarray = None
    pose_std_after: np.ndarray = None


class CooperativeLocalization(TeamScenario):
    """``cooperative_localization_v0`` as a scenario: see ``CooperativeLocalizationEnv`` for its spaces, rewards and
    config keys."""

    metadata = team_metadata("cooperative_localization_v0")
    episode_metrics = TEAM_LOCALIZATION_METRICS
    traits = EnvTraits(
        kb_per_copy=20,  # [kB] at the defaults, between peak RSS growth and traced allocations
        idle_actions=frozenset({NO_OBSERVATION}),
        reward_terms=("own_mutual_information", "team_mutual_information"),
        main_metric="cumulative_mi",
        info_keys=frozenset(
            {"gps_available", "pose_std", "pose_std_after_update", "pose_entropy", "position_error_m"}
            | {"heading_error_rad", "estimated_pose"}
        ),
        reward_config_keys=("team_reward",),
        noop_action=NO_OBSERVATION,
    )

    @classmethod
    def default_config(cls) -> dict:
        return team_localization_config()

    def __init__(self, config: dict, copies: int, owner: str, render_mode: str | None):
        super().__init__(config, copies, owner, render_mode)
        parts = TeamParts.of_config(config, owner)
        n_robots = len(parts.gps)
        low, high = team_observation_bounds(n_robots, config["observe_gains"])
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.action_space = spaces.Discrete(n_robots + 1)
        self.use_team(parts.pairs, parts.gps, parts.odometry)

    def allocate(self, copies: int) -> LocalizationState:
        shape = (copies, len(self.agents))
        return LocalizationState(
            **self.team_fields(copies),
            own_mi=np.zeros(shape),
            team_mi=np.zeros(shape),
            pose_std_after=np.zeros((*shape, POSE_DIM)),
        )

    def initial(self, state: LocalizationState, rows: np.ndarray, rngs: list) -> LocalizationState:
        """Draw each copy's scenario and joint prior (``start_episode``), then its first DGPS fixes."""
        for copy, rng in zip(rows.tolist(), rngs):
            self.start_copy(state, copy, *start_episode(self.config, rng, self.owner))
        self.started(state, rows)
        return state

    def decision(self, state: LocalizationState, rows) -> TeamDecision:
        """The observable pairs of the copies ``rows``, the candidates' models and expected gains at their priors."""
        pair_geometry, valid = observable_pairs(self.pairs, self.rows_geometry(state, rows), state.worlds.poses[rows])
        return TeamDecision.at_prior(
            self.pairs, pair_geometry, valid, state.x[rows], state.P[rows], self.config["team_reward"]
        )

    def transition(self, state: LocalizationState, decision: TeamDecision, action, acting) -> LocalizationState:
        """Fuse every copy's chosen observations as one stacked update, then move the robots of the ``acting`` copies,
        predict with their noisy odometry and fuse the DGPS fixes available."""
        chosen = np.where(action >= 0, action, NO_OBSERVATION)
        state.chosen, state.invalid = chosen, acting[:, None] & (action < 0)
        team_mi, state.own_mi, state.pose_std_after = self.relative_update(state, self.every_copy, chosen, decision)
        state.team_mi = np.repeat(team_mi[:, None], len(self.agents), axis=1)
        if acting[0] and self.drawing:  # drawn by ``frame``: copy 0's (observer, target) pairs
            state.observed_pairs = [(robot, int(j) - 1) for robot, j in enumerate(chosen[0]) if j != NO_OBSERVATION]
        copies = np.flatnonzero(acting)
        if copies.size:
            dt = self.config["time_step_s"]
            self.predict(state, copies, state.worlds.step(dt, copies), dt)
            self.gps_fixes(state, copies, state.elapsed[copies] + 1)  # the driver counts the step after
            self.moved(state, copies)
        return state

    def reward(self, decision, action, state: LocalizationState) -> np.ndarray:
        """Each robot's own-pose MI mixed with the team's by ``team_reward`` [nats]."""
        weight = self.config["team_reward"]
        return (1.0 - weight) * state.own_mi + weight * state.team_mi

    def observation(self, state: LocalizationState, decision: TeamDecision, rows) -> np.ndarray:
        gains = decision.action_information_gain if self.config["observe_gains"] else None
        valid, horizon = decision.action_mask[..., 1:] == 1, self.config["max_cycles"]
        return team_observations(state, decision, rows, horizon, valid, self.observation_space, gains)

    def info(self, state: LocalizationState, decision: TeamDecision, rows, stepped) -> dict:
        """The decision's masks and gains, the reward terms, the actions and the robots' estimates (``team_info``)."""
        std = np.where(stepped[:, None, None], state.pose_std_after[rows], decision.pose_std)
        terms = {"own_mutual_information": state.own_mi[rows], "team_mutual_information": state.team_mi[rows]}
        return self.team_info(state, decision, rows, stepped, terms, pose_std_after_update=std)

    def frame(self, state: LocalizationState, decision: TeamDecision) -> SceneFrame:
        """Copy 0 drawn: its scenario, every robot (truth, estimate, covariance, paths) and this step's observations."""
        time_s = state.elapsed[0] * self.config["time_step_s"]
        caption = f"t = {time_s:.1f} s   {len(state.observed_pairs)} relative observations this step"
        return self.team_frame(state, caption, observations=list(state.observed_pairs))


class CooperativeLocalizationVectorEnv(TeamAccessors, Driver, scenario=CooperativeLocalization):
    """N copies of ``cooperative_localization_v0`` (the driver's vector API, autoreset and arguments; spaces,
    rewards and config keys: ``CooperativeLocalizationEnv``).

    Observations (N, R, 10 + 5R); rewards, ``terminated``, ``truncated`` (N, R); infos (N, R, ...) (``time_s``
    (N,)); ``info["action_mask"]`` and ``action_masks()`` (N, R, R + 1).
    """


class CooperativeLocalizationEnv(ParallelEnvView, vector_env=CooperativeLocalizationVectorEnv):
    """Robots without (or losing) DGPS localize through relative-pose observations of teammates.

    ## Description
    The paper's Section III-C. N robots follow their routes in a Pymunk world; a joint EKF over all poses fuses
    every robot's odometry, the DGPS fixes of the robots that have them (DGPS drops out on a time schedule and under
    GPS-denied canopy zones) and the relative-pose observations the agents choose. Each step each robot may observe
    one teammate with its laser or camera: the measured range, bearing and relative heading update both robots'
    poses and correlate them. A greedy-entropy agent picks the teammate whose observation brings the most
    information on its own pose.

    ## Agents
    ``robot_0 .. robot_{N-1}`` (``team_field`` fits up to 4 robots in its default 40 m field; ``convoy`` any
    number). Each robot's sensor suite comes from ``robot_sensors`` (default: suite ``k % 4`` of ``gps+laser,
    gps+laser, laser, vision``; odometry always).

    ## Action Space
    ``Discrete(N + 1)`` per agent: 0 = no relative observation (always valid), ``1 + j`` = observe ``robot_j``.
    Valid when the robot carries a relative-pose sensor, ``robot_j`` is another robot inside its range and field of
    view and no wall or obstacle blocks the line of sight (``infos[agent]["action_mask"]``). A masked action is a
    no-op (``invalid_action="noop"``, the default, as in the single-agent envs) or raises ``ValueError``
    (``invalid_action="raise"``). An integer outside the space always raises ``ValueError``.

    ## Observation Space
    ``Box(float32, (10 + 5 N,))`` per agent: the robot's estimated ``x, y`` [m], ``cos, sin`` of its estimated
    heading, standard deviations of ``x, y`` [m] and heading [rad], its pose entropy [nats], whether it has a DGPS
    fix now, and the elapsed fraction of ``max_cycles``; then per robot ``j``: whether observing it is valid, its
    estimated range [m], ``cos, sin`` of its estimated bearing and its position standard deviation [m] (zeros for
    the robot itself). With ``observe_gains=True``, ``N + 1`` more: ``action_information_gain`` of each action (what
    a greedy agent ranks by [nats]), so ``Box(float32, (11 + 6 N,))``.

    ## Rewards
    The realized mutual information on the robot's own pose of this step's relative-pose updates, ``0.5 ln(det
    P_ii,prior / det P_ii,post)`` [nats], mixed with the team's (the MI on the joint state) by ``team_reward`` in
    [0, 1]: ``(1 - team_reward) * own + team_reward * team``. The observations of one step are taken at the same
    time and fused as one stacked EKF update, so a robot's reward also counts what teammates' observations of it
    brought; ``action_information_gain[a]`` is the MI action ``a`` alone would bring to the robot's own pose at the
    step's prior.

    ## Info
    ``infos[agent]``: ``action_mask`` (int8), ``action_information_gain`` (expected reward of each action [nats], 0
    where masked), ``reward_own_mutual_information`` and
    ``reward_team_mutual_information`` (the reward's terms), ``chosen_action``, ``invalid_action``, ``gps_available``,
    ``pose_std`` (x, y, heading std at the step's prior), ``pose_std_after_update`` (right after the step's relative
    updates), ``pose_entropy``, ``position_error_m``, ``heading_error_rad``, ``true_pose``, ``estimated_pose``,
    ``time_s``.

    ## Starting State
    The robots at their routes' starts; initial estimates drawn from ``N(true pose, diag(initial_position_std_m^2,
    ..., initial_heading_std_rad^2))``.

    ## Episode End
    All agents are truncated after ``max_cycles`` steps; never terminated.

    ## Arguments
    ``parallel_env(render_mode=None, **config)`` with any key of ``default_config()``; an unknown key raises
    ``ValueError`` naming it. The env is the N = 1 view of ``CooperativeLocalizationVectorEnv`` (its one
    implementation, ``self.vector``: ``scenario(0)``, ``true_poses``, ``joint_state()``); its EKF (the batched kernels)
    equals raw filterpy's update for update. ``estimator="independent"`` drops the cross-covariances (overconfident, for
    comparison).

    ## Version History
    * v0: initial version; the N = 1 view of the vector env since the one-implementation refactor (same numbers).
    """
