"""``ActiveLocalizationVectorEnv``: N copies of ``infonav/ActiveLocalization-v0`` stepped at once on stacked arrays.

``gym.make_vec("infonav/ActiveLocalization-v0", num_envs=N, **config)`` returns it. The estimation (EKF
prediction, range-bearing updates, expected gains, log-determinants) and the visibility run batched over
the copies (``estimation.batched``, ``world.visibility``), the physics in a ``WorldBatch`` driven by the
primitives' commands (numpy free motion, a copy's own Pymunk space for its contact steps) and the sensor noise
from one stream per copy (``NoiseStreams``, the single env's generators drawn ahead). So sub-env ``i`` after
``reset(seed=s)`` gives the numbers of ``gym.make("infonav/ActiveLocalization-v0")`` after ``reset(seed=s + i)``.
"""

from __future__ import annotations

import numpy as np

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
from infonav_gym.envs.landmark_decision import LandmarkDecision
from infonav_gym.envs.one_robot_vector import OneRobotVectorEnv
from infonav_gym.envs.vector_infos import set_rows
from infonav_gym.estimation import batched
from infonav_gym.estimation.ekf import POSE_DIM
from infonav_gym.information import largest_position_std, log_det_spd
from infonav_gym.world.visibility import StaticGeometry


class ActiveLocalizationVectorEnv(OneRobotVectorEnv, single_env=ActiveLocalizationEnv):
    """N copies of ``ActiveLocalizationEnv`` (see it for the spaces, rewards and config keys), batched.

    ## Vector API
    ``single_observation_space`` / ``single_action_space`` are the single env's; ``step`` takes one
    action per sub-env (N,) and returns observations (N, 14 + 4K + 4O), rewards, ``terminated`` (goal
    reached or uncertainty bound crossed) and ``truncated`` (horizon) (N,). Infos hold the single env's
    keys as arrays with a leading N dimension, each with Gymnasium's ``_key`` mask (``reward_terms`` is a
    dict of such arrays, all six terms); ``info["action_mask"]`` is (N, 5 (1 + K)). ``action_masks()``
    gives the bool masks for ``MaskablePPO``.

    ## Autoreset
    ``autoreset_mode`` (``metadata["autoreset_mode"]``) is Gymnasium's ``NEXT_STEP`` by default, as its
    ``CartPoleVectorEnv``: the step after a sub-env's episode ended (terminated or truncated) resets it (its
    action is ignored), with reward 0, not terminated nor truncated, and its reset info (``reward_terms``
    masked out). With ``SAME_STEP`` the step that ends an episode returns the reset observation and info,
    with the last observation and info in ``info["final_obs"]`` (an object array, ``None`` for the others)
    and ``info["final_info"]``, masked by ``info["_final_obs"]`` / ``"_final_info"``. A sub-env reset this
    way continues its own generator, as the single env's ``reset()`` without a seed does.

    ## Arguments
    ``num_envs`` (N >= 1), ``autoreset_mode`` (an ``AutoresetMode`` or its value, ``"NextStep"`` /
    ``"SameStep"``) and any key of ``ActiveLocalizationEnv.default_config()``, checked as the single env
    checks them. ``render_mode`` (``"rgb_array"`` or ``"human"``): ``render()`` draws sub-env 0, as its single
    env would (``FirstCopyView``). The planning model is the single env's.
    """

    def _allocate(self) -> None:
        num_envs = self.num_envs
        n_landmarks, n_obstacles = self.config["n_candidates"], self.config["n_obstacles"]
        self._state = {  # what batched_info reads, per copy
            "x": np.zeros((num_envs, POSE_DIM)),
            "P": np.zeros((num_envs, POSE_DIM, POSE_DIM)),
            "goals": np.zeros((num_envs, 2)),
            "elapsed": np.zeros(num_envs, dtype=int),
            "observations_left": np.zeros(num_envs, dtype=int),
            "goal_reached": np.zeros(num_envs, dtype=bool),
            "failed": np.zeros(num_envs, dtype=bool),
        }
        self._landmarks = np.zeros((num_envs, n_landmarks, 2))
        self._obstacle_centers = np.zeros((num_envs, n_obstacles, 2))
        self._obstacle_radii = np.zeros((num_envs, n_obstacles))

    def _reset_copies(self, copies: np.ndarray) -> StaticGeometry:
        """Start a new episode in each of ``copies`` from its own generator; the static geometry of those copies."""
        state, geometries = self._state, []
        self._view_restarts(copies)
        for copy in copies.tolist():
            scenario, prior, odometry_rng, measurement_rng = start_episode(self.config, self._np_randoms[copy])
            self._worlds.reset_copy(copy, scenario)
            self._odometry_noise.restart(copy, odometry_rng)
            self._measurement_noise.restart(copy, measurement_rng)
            state["x"][copy], state["P"][copy] = prior.state()
            state["goals"][copy] = episode_goal(scenario)
            self._obstacle_centers[copy], self._obstacle_radii[copy] = obstacle_discs(scenario)
            self._landmarks[copy] = scenario.landmarks
            geometries.append(StaticGeometry.from_scenario(scenario, self._worlds.wall_thickness_m))
        state["elapsed"][copies] = 0
        state["observations_left"][copies] = self.config["max_observations"]
        state["goal_reached"][copies] = state["failed"][copies] = False
        return StaticGeometry.stack(geometries)

    def step(self, actions):
        """Act in every sub-env, with ``autoreset_mode``'s resets (see the class; errors: ``_begin_step``)."""
        acting, chosen = self._begin_step(actions)
        terms = self._act(np.flatnonzero(acting), chosen)
        state = self._state
        terminated = acting & (state["goal_reached"] | state["failed"])
        truncated = acting & ~terminated & (state["elapsed"] >= self.config["horizon"])
        rewards = np.zeros(self.num_envs)
        for key in REWARD_TERMS:
            rewards += terms[key]
        observation, info = self._finish_step(
            terminated | truncated, lambda copies, geometry: self._outputs(copies, geometry, acting, chosen, terms)
        )
        return observation, rewards, terminated, truncated, info

    def _act(self, copies: np.ndarray, chosen: np.ndarray) -> dict:
        """The whole transition of the acting ``copies`` (observe, then drive); their reward terms (N,) each.

        A no-op (``chosen`` -1) stands still observing nothing, as in the single env.
        """
        cfg, state = self.config, self._state
        terms = {key: np.zeros(self.num_envs) for key in REWARD_TERMS}
        slots, primitives = np.divmod(chosen, N_PRIMITIVES)
        observed, terms["mutual_information"] = self._observe(np.where(chosen >= 0, slots - 1, -1))
        terms["sensing_cost"][observed] = -cfg["observation_cost_nats"]
        state["observations_left"] -= observed
        if not copies.size:
            return terms
        driving = chosen[copies] >= 0
        goals = state["goals"][copies]
        commands = primitive_commands(cfg, goals, state["x"][copies], primitives[copies])
        commands[~driving] = 0.0
        distance_before = self._distances_to_goal(copies)
        self._drive(copies, commands)
        distance_after = self._distances_to_goal(copies)
        terms["motion_cost"][copies] = np.where(driving, -cfg["motion_cost_per_step"], 0.0)
        progress = cfg["progress_reward_per_m"] * (distance_before - distance_after)
        terms["progress"][copies] = np.where(driving, progress, 0.0)
        reached = distance_after <= cfg["goal_radius_m"]
        failed = ~reached & (largest_position_std(state["P"][copies]) > cfg["max_position_std_m"])
        state["goal_reached"][copies], state["failed"][copies] = reached, failed
        terms["goal_bonus"][copies] = np.where(reached, cfg["goal_bonus"], 0.0)
        terms["failure_penalty"][copies] = np.where(failed, -cfg["failure_penalty"], 0.0)
        state["elapsed"][copies] += 1
        return terms

    def _distances_to_goal(self, copies: np.ndarray) -> np.ndarray:
        """The true distance of each of ``copies`` to its goal [m] (n,)."""
        offsets = self._worlds.poses[copies, 0, :2] - self._state["goals"][copies]
        return np.hypot(offsets[:, 0], offsets[:, 1])

    def _observe(self, landmarks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Update each observing copy's EKF with a noisy measurement of its landmark (-1: none).

        Returns:
            ``(observed (N,) bool, realized MI (N,) [nats])``.
        """
        sight, state = self._decision.sight, self._state
        observed, predicted, H, R = batched.select_candidates(landmarks, sight.predicted, sight.H, sight.R)
        mutual_information = np.zeros(self.num_envs)
        observers = np.flatnonzero(observed)
        if not observers.size:
            return observed, mutual_information
        measurements = np.zeros((self.num_envs, 2))
        measurements[observers] = self._sensor.measure_with_noise(
            self._worlds.poses[observers, 0],
            self._landmarks[observers, landmarks[observers]],
            self._measurement_noise.take(observers),
        )
        state["x"], state["P"] = batched.range_bearing_update(
            state["x"], state["P"], measurements, predicted, H, R, observed, check_input=False
        )
        posterior_log_dets = log_det_spd(state["P"][observers], check_input=False)
        mutual_information[observers] = 0.5 * (sight.prior_log_det[observers] - posterior_log_dets)
        return observed, mutual_information

    def _drive(self, copies: np.ndarray, commands: np.ndarray) -> None:
        """Drive the worlds of ``copies`` by their ``[speed, turn rate]`` commands (n, 2); predict their EKFs."""
        state = self._state
        state["x"][copies], state["P"][copies] = self._moved(copies, state["x"][copies], state["P"][copies], commands)

    def _reset_outputs(self, copies: np.ndarray, geometry: StaticGeometry) -> tuple[np.ndarray, dict]:
        """The observations and reset infos of ``copies``, just reset (``geometry``: theirs)."""
        nothing = np.zeros(len(copies))
        terms = dict.fromkeys(REWARD_TERMS, nothing)
        return self._outputs(copies, geometry, nothing.astype(bool), np.full(len(copies), -1), terms)

    def _outputs(self, copies, geometry, stepped, chosen, terms) -> tuple[np.ndarray, dict]:
        """Decide again at the priors of ``copies`` (geometry: theirs); their observations and infos.

        Args:
            copies: the copies (n,).
            geometry: their static geometry (n copies).
            stepped: which of them acted in this step (n,) bool; the others give their reset info.
            chosen: the action each took (n,), -1 for a no-op.
            terms: their reward terms, each (n,) [nats].
        """
        state = {key: value[copies] for key, value in self._state.items()}
        true_poses, x, P = self._worlds.poses[copies, 0], state["x"], state["P"]
        everywhere = np.ones((len(copies), self._landmarks.shape[1]), dtype=bool)
        sight = LandmarkDecision.at_prior(
            self._sensor, geometry, true_poses, x, P, self._landmarks[copies], everywhere, mapping=False
        )
        decision = ActiveDecision.from_sight(sight, state["observations_left"])
        if len(copies) == self.num_envs:
            self._decision = decision
        else:
            self._decision.action_mask[copies] = decision.action_mask
            self._decision.action_information_gain[copies] = decision.action_information_gain
            set_rows(self._decision.sight._asdict(), copies, sight._asdict())
        obstacles = (self._obstacle_centers[copies], self._obstacle_radii[copies])
        observation = batched_observation(
            decision,
            x,
            P,
            state["elapsed"],
            state["observations_left"],
            state["goals"],
            obstacles,
            self.config,
            self.single_observation_space,
        )
        state["true_poses"] = true_poses
        return observation, batched_info(decision, state, stepped, chosen, terms, self.config)
