"""``ActiveLocalizationVectorEnv``: N copies of ``infonav/ActiveLocalization-v0`` stepped at once on stacked arrays.

``gym.make_vec("infonav/ActiveLocalization-v0", num_envs=N, **config)`` returns it. The estimation (EKF
prediction, range-bearing updates, expected gains, log-determinants) and the visibility run batched over
the copies (``estimation.batched``, ``world.visibility``); the physics keeps one Pymunk ``CommandedWorld`` per
copy and the sensor noise one generator per copy, drawn in the single env's order. So sub-env ``i`` after
``reset(seed=s)`` gives the numbers of ``gym.make("infonav/ActiveLocalization-v0")`` after ``reset(seed=s + i)``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from gymnasium.vector import AutoresetMode

from infonav_gym.envs.active_localization import (
    REWARD_TERMS,
    ActiveLocalizationEnv,
    episode_goal,
    obstacle_discs,
    primitive_commands,
    start_episode,
)
from infonav_gym.envs.active_localization_batch import ActiveDecision, batched_info, batched_observation
from infonav_gym.envs.active_planning import N_PRIMITIVES
from infonav_gym.envs.landmark_selection_batch import BatchedDecision
from infonav_gym.envs.vector_base import InfoNavVectorEnv
from infonav_gym.estimation import batched
from infonav_gym.estimation.ekf import POSE_DIM
from infonav_gym.information import log_det_spd
from infonav_gym.world.active_scenarios import CommandedWorld
from infonav_gym.world.visibility import StaticGeometry


class ActiveLocalizationVectorEnv(InfoNavVectorEnv):
    """N copies of ``ActiveLocalizationEnv`` (see it for the spaces, rewards and config keys), batched.

    ## Vector API
    ``single_observation_space`` / ``single_action_space`` are the single env's; ``step`` takes one
    action per sub-env (N,) and returns observations (N, 14 + 4K + 4O), rewards, ``terminated`` (goal
    reached or uncertainty bound crossed) and ``truncated`` (horizon) (N,). Infos hold the single env's
    keys as arrays with a leading N dimension, each with Gymnasium's ``_key`` mask (``reward_terms`` is a
    dict of such arrays); ``info["action_mask"]`` is (N, 5 (1 + K)). ``action_masks()`` gives the bool
    masks for ``MaskablePPO``.

    ## Autoreset
    ``NEXT_STEP`` (``metadata["autoreset_mode"]``), as Gymnasium's ``CartPoleVectorEnv``: the step after a
    sub-env's episode ended (terminated or truncated) resets it (its action is ignored), with reward 0,
    not terminated nor truncated, and its reset info (``reward_terms`` masked out). A sub-env reset this
    way continues its own generator, as the single env's ``reset()`` without a seed does.

    ## Arguments
    ``num_envs`` (N >= 1) and any key of ``ActiveLocalizationEnv.default_config()``, checked as the
    single env checks them. Rendering is not implemented yet; the planning model is the single env's.
    """

    metadata = {**InfoNavVectorEnv.metadata, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, render_mode: str | None = None, **config):
        single = ActiveLocalizationEnv(**config)  # checks the config as the single env does
        self._configure(num_envs, render_mode, single)
        self._sensor, self._odometry = single.sensor, single.odometry
        self._odometry_covariance = self._odometry.noise_covariance()
        self._worlds = [CommandedWorld() for _ in range(num_envs)]
        self._odometry_rngs: list[np.random.Generator | None] = [None] * num_envs
        self._measurement_rngs: list[np.random.Generator | None] = [None] * num_envs
        self._geometry = None
        n_landmarks, n_obstacles = self.config["n_candidates"], self.config["n_obstacles"]
        self._state = {
            "x": np.zeros((num_envs, POSE_DIM)),
            "P": np.zeros((num_envs, POSE_DIM, POSE_DIM)),
            "true_poses": np.zeros((num_envs, POSE_DIM)),
            "goals": np.zeros((num_envs, 2)),
            "elapsed": np.zeros(num_envs, dtype=int),
            "observations_left": np.zeros(num_envs, dtype=int),
            "goal_reached": np.zeros(num_envs, dtype=bool),
            "failed": np.zeros(num_envs, dtype=bool),
        }
        self._landmarks = np.zeros((num_envs, n_landmarks, 2))
        self._obstacles = (np.zeros((num_envs, n_obstacles, 2)), np.zeros((num_envs, n_obstacles)))
        self._prev_done = np.zeros(num_envs, dtype=bool)

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset every sub-env: seed ``s`` gives sub-env ``i`` the seed ``s + i``; a list gives one seed (or None) each.

        Raises:
            ValueError: for a seed that is not None, an int >= 0 or a list of N ints / None, or any options.
        """
        self._seed_sub_envs(seed, options)
        self._reset_copies(np.arange(self.num_envs))
        self._prev_done[:] = False
        terms = {key: np.zeros(self.num_envs) for key in REWARD_TERMS}
        return self._outputs(np.zeros(self.num_envs, dtype=bool), np.full(self.num_envs, -1), terms)

    def _reset_copies(self, copies: np.ndarray) -> None:
        """Start a new episode in each of ``copies`` from its own generator, as the single env's reset does."""
        state = self._state
        centers, radii = self._obstacles
        for copy in copies.tolist():
            world = self._worlds[copy]
            ekf, self._odometry_rngs[copy], self._measurement_rngs[copy] = start_episode(
                self.config, world, self._np_randoms[copy]
            )
            state["x"][copy], state["P"][copy] = ekf.x, ekf.P
            state["true_poses"][copy] = world.pose
            state["goals"][copy] = episode_goal(world.scenario)
            centers[copy], radii[copy] = obstacle_discs(world.scenario)
            self._landmarks[copy] = world.landmarks
        state["elapsed"][copies] = 0
        state["observations_left"][copies] = self.config["max_observations"]
        state["goal_reached"][copies] = state["failed"][copies] = False
        self._restack_geometry(copies)

    def _restack_geometry(self, copies: np.ndarray) -> None:
        """Put the static shapes of the worlds of ``copies`` (just reset) into the stacked geometry.

        Every goal field has the same walls and obstacle count, so only those copies' rows change.
        """
        fresh = StaticGeometry.stack([StaticGeometry.from_world(self._worlds[copy]) for copy in copies.tolist()])
        if len(copies) == self.num_envs:
            self._geometry = fresh
            return
        rows = {}
        for field in dataclasses.fields(StaticGeometry):
            rows[field.name] = getattr(self._geometry, field.name).copy()
            rows[field.name][copies] = getattr(fresh, field.name)
        self._geometry = StaticGeometry(**rows)

    def step(self, actions):
        """Act in every sub-env (reset those whose episode ended at the last step, see the class).

        Raises:
            ValueError: for actions that are not N integers of the action space, or, with
                ``invalid_action="raise"``, a masked action (each naming its sub-env).
        """
        actions = self._checked_actions(actions)
        resetting = self._prev_done.copy()
        acting = ~resetting
        chosen = self._accepted_actions(actions, acting)
        terms = self._act(np.flatnonzero(acting), chosen)
        if resetting.any():
            self._reset_copies(np.flatnonzero(resetting))
        state = self._state
        terminated = acting & (state["goal_reached"] | state["failed"])
        truncated = acting & ~terminated & (state["elapsed"] >= self.config["horizon"])
        rewards = np.zeros(self.num_envs)
        for key in REWARD_TERMS:
            rewards += terms[key]
        observation, info = self._outputs(acting, chosen, terms)
        self._prev_done = terminated | truncated
        return observation, rewards, terminated, truncated, info

    def _act(self, copies: np.ndarray, chosen: np.ndarray) -> dict:
        """The whole transition of the acting ``copies`` (observe, then drive); their reward terms (N,) each.

        A no-op (``chosen`` -1) stands still observing nothing, as in the single env.
        """
        cfg, state = self.config, self._state
        terms = {key: np.zeros(self.num_envs) for key in REWARD_TERMS}
        slots, primitives = np.divmod(chosen, N_PRIMITIVES)
        landmarks = np.where(chosen >= 0, slots - 1, -1)
        observed, terms["mutual_information"] = self._observe(landmarks)
        terms["sensing_cost"][observed] = -cfg["observation_cost_nats"]
        state["observations_left"] -= observed
        if not copies.size:
            return terms
        driving = chosen[copies] >= 0
        goals = state["goals"][copies]
        commands = primitive_commands(cfg, goals, state["x"][copies], primitives[copies])
        commands[~driving] = 0.0
        distance_before = np.hypot(*(state["true_poses"][copies, :2] - goals).T)
        self._drive(copies, commands)
        distance_after = np.hypot(*(state["true_poses"][copies, :2] - goals).T)
        terms["motion_cost"][copies] = np.where(driving, -cfg["motion_cost_per_step"], 0.0)
        progress = cfg["progress_reward_per_m"] * (distance_before - distance_after)
        terms["progress"][copies] = np.where(driving, progress, 0.0)
        reached = distance_after <= cfg["goal_radius_m"]
        failed = ~reached & (ActiveLocalizationEnv.position_std(state["P"][copies]) > cfg["max_position_std_m"])
        state["goal_reached"][copies], state["failed"][copies] = reached, failed
        terms["goal_bonus"][copies] = np.where(reached, cfg["goal_bonus"], 0.0)
        terms["failure_penalty"][copies] = np.where(failed, -cfg["failure_penalty"], 0.0)
        state["elapsed"][copies] += 1
        return terms

    def _observe(self, landmarks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Update each observing copy's EKF with a noisy measurement of its landmark (-1: none).

        Returns:
            ``(observed (N,) bool, realized MI (N,) [nats])``.
        """
        sight, state = self._decision.sight, self._state
        observed, predicted, H, R = batched.select_candidates(landmarks, sight.predicted, sight.H, sight.R)
        mutual_information = np.zeros(self.num_envs)
        if not observed.any():
            return observed, mutual_information
        measurements = self._measurements(observed, landmarks)
        state["x"], state["P"] = batched.range_bearing_update(
            state["x"], state["P"], measurements, predicted, H, R, observed, check_input=False
        )
        posterior_log_dets = log_det_spd(state["P"][observed], check_input=False)
        mutual_information[observed] = 0.5 * (sight.prior_log_det[observed] - posterior_log_dets)
        return observed, mutual_information

    def _measurements(self, observed: np.ndarray, landmarks: np.ndarray) -> np.ndarray:
        """Noisy ``[range, bearing]`` of each observing copy's landmark from its true pose (N, 2), its own generator."""
        measurements = np.zeros((self.num_envs, 2))
        true_poses = self._state["true_poses"]
        for copy in np.flatnonzero(observed).tolist():
            landmark = self._landmarks[copy, landmarks[copy]]
            measurements[copy] = self._sensor.measure(true_poses[copy], landmark, self._measurement_rngs[copy])
        return measurements

    def _drive(self, copies: np.ndarray, commands: np.ndarray) -> None:
        """Drive the worlds of ``copies`` by their ``[speed, turn rate]`` commands; predict their EKFs from odometry."""
        dt, state = self.config["time_step_s"], self._state
        readings = np.zeros((len(copies), 2))
        for row, copy in enumerate(copies.tolist()):
            world = self._worlds[copy]
            world.command(*commands[row])
            control = world.step(dt)[0]
            state["true_poses"][copy] = world.pose
            readings[row] = self._odometry.measure(control, self._odometry_rngs[copy])
        state["x"][copies], state["P"][copies] = batched.predict_pose(
            state["x"][copies], state["P"][copies], readings, dt, self._odometry_covariance, check_input=False
        )

    def _outputs(self, stepped: np.ndarray, chosen: np.ndarray, terms: dict) -> tuple[np.ndarray, dict]:
        """Decide again at every copy's prior; the observations and infos of this reset or step."""
        state = self._state
        everywhere = np.ones(self._landmarks.shape[:2], dtype=bool)
        sight = BatchedDecision.at_prior(
            self._sensor,
            self._geometry,
            state["true_poses"],
            state["x"],
            state["P"],
            self._landmarks,
            everywhere,
            mapping=False,
        )
        self._decision = ActiveDecision.from_sight(sight, state["observations_left"])
        observation = batched_observation(
            self._decision,
            state["x"],
            state["P"],
            state["elapsed"],
            state["observations_left"],
            state["goals"],
            self._obstacles,
            self.config,
            self.single_observation_space,
        )
        return observation, batched_info(self._decision, state, stepped, chosen, terms, self.config)

    def close_extras(self, **kwargs) -> None:
        self._worlds = []
        self._decision = None
