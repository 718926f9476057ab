"""``CooperativeLocalizationVectorEnv``: ``cooperative_localization_v0`` written once, N copies on stacked arrays.

``make_vector_env("cooperative_localization_v0", num_envs=N, **config)`` returns it; its PettingZoo env
(``CooperativeLocalizationEnv``, ``cooperative_localization_v0.parallel_env``) is its N = 1 view without autoreset
(``multi.parallel_view``). The joint estimation (prediction, DGPS and relative-pose updates, expected gains,
log-determinants) runs on the batched EKF core (``estimation.batched``), the robot-robot line of sight on
``world.visibility``, the physics in a ``WorldBatch`` (numpy free motion, a copy's own Pymunk space for its contact
steps) and the sensor noise from one stream per copy and sensor (``NoiseStreams``), so copy ``i`` after
``reset(seed=s)`` gives the numbers of ``parallel_env()`` after ``reset(seed=s + i)``.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode

from infonav_gym.envs.metrics import TEAM_LOCALIZATION_METRICS
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.multi.parallel_view import team_metadata
from infonav_gym.multi.team_decision import TeamDecision, TeamStep, observable_pairs, team_info
from infonav_gym.multi.team_localization import TeamParts, start_episode, team_localization_config
from infonav_gym.multi.team_observations import team_observation_bounds, team_observations
from infonav_gym.multi.team_paths import FirstCopyPaths
from infonav_gym.multi.team_sensing import NO_OBSERVATION
from infonav_gym.multi.team_vector import TeamVectorEnv
from infonav_gym.scene import SceneFrame
from infonav_gym.world.visibility import StaticGeometry


class CooperativeLocalizationVectorEnv(TeamVectorEnv):
    """N copies of ``cooperative_localization_v0`` on stacked arrays: the env's one implementation.

    See ``CooperativeLocalizationEnv`` (its N = 1 PettingZoo view) for the spaces, rewards and config keys.

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
    ``DISABLED``: a copy goes on from its last state until ``reset()`` (what the PettingZoo view steps).

    ## Arguments
    ``num_envs`` (N >= 1), ``autoreset_mode`` (an ``AutoresetMode``, its value or its name ``"same_step"``) and
    any key of ``default_config()``. ``render_mode`` (``"rgb_array"`` or ``"human"``): ``render()`` draws copy 0:
    the scenario, each robot's truth, estimate, covariance and paths, and this step's relative observations.
    """

    metadata = {**team_metadata("cooperative_localization_v0"), "autoreset_mode": AutoresetMode.NEXT_STEP}
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
        """A fresh dict of every config key with its default."""
        return team_localization_config()

    def _build(self) -> None:
        num_envs = self.num_envs
        cfg = self.config
        parts = TeamParts.of_config(cfg, self.owner_name)
        n_robots = len(parts.suites)
        low, high = team_observation_bounds(n_robots, cfg["observe_gains"])
        observation_space = spaces.Box(low, high, dtype=np.float32)
        self._setup_team(observation_space, spaces.Discrete(n_robots + 1), parts.pairs, parts.gps, parts.odometry)
        self._geometries: list[StaticGeometry | None] = [None] * num_envs
        self._geometry: StaticGeometry | None = None  # every copy's, stacked
        self._paths: FirstCopyPaths | None = None  # copy 0's paths, kept to draw them
        self._observed_pairs: list[tuple[int, int]] = []  # copy 0's relative observations of the last step

    # ------------------------------------------------------------------ the state, for harnesses and tests

    @property
    def decision(self) -> TeamDecision:
        """The current decision of every copy (masks, expected gains, the candidates' models at the prior)."""
        return self._decision

    # ------------------------------------------------------------------ reset and step

    def _reset_copies(self, copies: np.ndarray) -> None:
        """Start a new episode in each of ``copies`` from its own generator."""
        for copy in copies.tolist():
            scenario, poses, covariances, *generators = start_episode(
                self.config, self._np_randoms[copy], self.owner_name
            )
            self._start_copy(copy, scenario, poses, covariances, generators)
            self._geometries[copy] = StaticGeometry.from_scenario(scenario, self._worlds.wall_thickness_m)
        self._geometry = StaticGeometry.stack(self._geometries)
        self._started(copies)
        if copies[0] == 0 and self.render_mode is not None:
            self._paths = FirstCopyPaths(self._worlds.poses[0], self._x[0].reshape(-1, POSE_DIM))
            self._observed_pairs = []

    def _reset_record(self) -> TeamStep:
        return TeamStep.of_reset(*self._gps_available.shape)

    def _act(self, chosen: np.ndarray, invalid: np.ndarray, acting: np.ndarray) -> tuple:
        """Observe, then move the ``acting`` copies; each robot's reward mixes its own and the team's MI."""
        own_mi, team_mi, updated_std = self._observe(chosen)
        copies = np.flatnonzero(acting)
        if acting[0] and self.render_mode is not None:  # drawn by render()
            observers = np.flatnonzero(chosen[0] != NO_OBSERVATION)
            self._observed_pairs = list(zip(observers.tolist(), (chosen[0, observers] - 1).tolist()))
        self._elapsed[copies] += 1
        self._advance(copies)
        weight = self.config["team_reward"]
        rewards = np.where(acting[:, None], (1.0 - weight) * own_mi + weight * team_mi, 0.0)
        return TeamStep(acting, chosen, invalid, own_mi, team_mi, updated_std), rewards, np.zeros_like(acting)

    def _restarted(self, record: TeamStep, copies: np.ndarray) -> TeamStep:
        """``record`` with the (N,) bool ``copies`` reset since: no action, no MI, not stepped."""
        rows = copies[:, None]
        return record._replace(
            stepped=record.stepped & ~copies,
            chosen=np.where(rows, NO_OBSERVATION, record.chosen),
            invalid=record.invalid & ~rows,
            own_mi=np.where(rows, 0.0, record.own_mi),
            team_mi=np.where(rows, 0.0, record.team_mi),
        )

    def _observe(self, chosen: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fuse each copy's chosen observations as one stacked update; the own and team MI (N, R) and the new std
        (MI 0 and the prior's std where a copy observes nothing)."""
        team_mi, own_mi, updated_std = self._relative_update(np.arange(self.num_envs), chosen, self._decision)
        return own_mi, np.repeat(team_mi[:, None], len(self.agents), axis=1), updated_std

    def _advance(self, copies: np.ndarray) -> None:
        """Move the robots of ``copies``, predict with their noisy odometry, then fuse the DGPS fixes available."""
        if not copies.size:
            return
        dt = self.config["time_step_s"]
        self._predict(copies, self._worlds.step(dt, copies), dt)
        self._gps_fixes(copies)
        if copies[0] == 0 and self._paths is not None:
            self._paths.extend(self._worlds.poses[0], self._x[0].reshape(-1, POSE_DIM))

    # ------------------------------------------------------------------ outputs

    def _decide(self) -> None:
        geometry, valid = observable_pairs(self._pairs, self._geometry, self._worlds.poses)
        weight = self.config["team_reward"]
        self._decision = TeamDecision.at_prior(self._pairs, geometry, valid, self._x, self._P, weight)

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
            self._elapsed / self.max_cycles,
            decision.action_mask[..., 1:] == 1,
            self.single_observation_space,
            decision.action_information_gain if self.config["observe_gains"] else None,
        )
        time_s = self._elapsed * self.config["time_step_s"]
        return observations, team_info(decision, last, self._x, self._worlds.poses, self._gps_available, time_s)

    # ------------------------------------------------------------------ rendering

    def _scene_frame(self) -> SceneFrame:
        """Copy 0 drawn: its scenario, every robot (truth, estimate, covariance, paths) and this step's observations."""
        scenario = self._worlds.scenario(0)
        time_s = self._elapsed[0] * self.config["time_step_s"]
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            robots=self._paths.drawings(
                self._worlds.poses[0], self._x[0], self._P[0], self.agents, self._gps_available[0]
            ),
            observations=list(self._observed_pairs),
            gps_denied_zones=scenario.gps_denied_zones,
            caption=f"t = {time_s:.1f} s   {len(self._observed_pairs)} relative observations this step",
        )
