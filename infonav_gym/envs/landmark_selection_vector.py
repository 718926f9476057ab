"""``LandmarkSelectionVectorEnv``: N copies of ``infonav/LandmarkSelection-v0`` stepped at once on stacked arrays.

``gym.make_vec("infonav/LandmarkSelection-v0", num_envs=N, **config)`` returns it. The estimation (EKF
prediction, range-bearing updates, expected gains, log-determinants) and the visibility run batched over
the copies (``estimation.batched``, ``world.visibility``), the physics in a ``WorldBatch`` (numpy free motion, a
copy's own Pymunk space for its contact steps) and the sensor noise from one stream per copy (``NoiseStreams``,
the single env's generators drawn ahead). So sub-env ``i`` after ``reset(seed=s)`` gives the numbers of
``gym.make("infonav/LandmarkSelection-v0")`` after ``reset(seed=s + i)``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from infonav_gym.envs.base import accepts_action
from infonav_gym.envs.landmark_selection import LandmarkSelectionEnv, start_episode
from infonav_gym.envs.landmark_selection_batch import BatchedDecision, batched_info, batched_observation
from infonav_gym.envs.noise_streams import NoiseStreams
from infonav_gym.envs.vector_infos import autoreset_mode_of, final_step_infos, set_rows
from infonav_gym.envs.vector_view import FirstCopyView
from infonav_gym.estimation import batched
from infonav_gym.world.visibility import StaticGeometry
from infonav_gym.world.world_batch import WorldBatch


class LandmarkSelectionVectorEnv(VectorEnv):
    """N copies of ``LandmarkSelectionEnv`` (see it for the spaces, rewards and config keys), batched.

    ## Vector API
    ``single_observation_space`` / ``single_action_space`` are the single env's; ``step`` takes one
    action per sub-env (N,) and returns observations (N, 10 + 5K), rewards, ``terminated`` and
    ``truncated`` (N,). Infos hold the single env's keys as arrays with a leading N dimension, each with
    Gymnasium's ``_key`` mask; ``info["action_mask"]`` is (N, K). ``action_masks()`` gives the (N, K)
    bool masks for ``MaskablePPO``.

    ## Autoreset
    ``autoreset_mode`` (``metadata["autoreset_mode"]``) is Gymnasium's ``NEXT_STEP`` by default, as its
    ``CartPoleVectorEnv``: the step after a sub-env's episode ended resets it (its action is ignored), with
    reward 0, not terminated nor truncated, and its reset info (``reward_terms`` masked out). With
    ``SAME_STEP`` (what SB3-style training wants) the step that ends an episode returns the reset
    observation and info, with the last observation and info in ``info["final_obs"]`` (an object array,
    ``None`` for the others) and ``info["final_info"]``, masked by ``info["_final_obs"]`` / ``"_final_info"``.
    A sub-env reset this way continues its own generator, as the single env's ``reset()`` without a seed does.

    ## Arguments
    ``num_envs`` (N >= 1), ``autoreset_mode`` (an ``AutoresetMode`` or its value, ``"NextStep"`` /
    ``"SameStep"``) and any key of ``LandmarkSelectionEnv.default_config()``, checked as the single env
    checks them. With ``mapping=True`` every copy's scenario must have the same number of landmarks
    (the stacked states share their size). ``render_mode`` (``"rgb_array"`` or ``"human"``): ``render()``
    draws sub-env 0, as its single env would (``FirstCopyView``).
    """

    metadata = {
        "render_modes": LandmarkSelectionEnv.metadata["render_modes"],
        "render_fps": LandmarkSelectionEnv.metadata["render_fps"],
        "autoreset_mode": AutoresetMode.NEXT_STEP,
    }
    _AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **config,
    ):
        owner = type(self).__name__
        if type(num_envs) is not int or num_envs < 1:
            raise ValueError(f"num_envs of {owner} must be an int >= 1, got {num_envs!r}")
        self.autoreset_mode = autoreset_mode_of(autoreset_mode, self._AUTORESET_MODES, owner)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        self._single = LandmarkSelectionEnv(**config)  # checks the config as the single env does
        self.config = self._single.config
        self.num_envs = num_envs
        self.render_mode = render_mode
        self._view = None if render_mode is None else FirstCopyView(LandmarkSelectionEnv(render_mode, **config))
        self.single_observation_space = self._single.observation_space
        self.single_action_space = self._single.action_space
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._sensor, self._odometry = self._single.sensor, self._single.odometry
        self._odometry_covariance = self._odometry.noise_covariance()
        self._worlds = WorldBatch(num_envs)
        self._odometry_noise, self._measurement_noise = NoiseStreams(num_envs, 2), NoiseStreams(num_envs, 2)
        self._np_randoms: list[np.random.Generator | None] = [None] * num_envs
        self._x = self._P = self._decision = self._geometry = None
        self._elapsed = np.zeros(num_envs, dtype=int)
        n_candidates = self.config["n_candidates"]
        self._landmarks = np.zeros((num_envs, n_candidates, 2))
        self._exists = np.zeros((num_envs, n_candidates), dtype=bool)
        self._prev_done = np.zeros(num_envs, dtype=bool)

    @property
    def np_randoms(self) -> list[np.random.Generator | None]:
        """Each sub-env's generator (the single env's ``np_random``), None before its first reset."""
        return list(self._np_randoms)

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset every sub-env: seed ``s`` gives sub-env ``i`` the seed ``s + i``; a list gives one seed (or None) each.

        Raises:
            ValueError: for a seed that is not None, an int or a list of N ints / None, or any options.
        """
        if options:
            raise ValueError(f"{type(self).__name__}.reset takes no options, got {sorted(options)}")
        for copy, copy_seed in enumerate(self._copy_seeds(seed)):
            if copy_seed is not None or self._np_randoms[copy] is None:
                self._np_randoms[copy] = seeding.np_random(copy_seed)[0]
        everyone = np.arange(self.num_envs)
        self._geometry = self._reset_copies(everyone)
        self._prev_done[:] = False
        nothing = np.zeros(self.num_envs)
        return self._outputs(
            everyone, self._geometry, np.zeros(self.num_envs, dtype=bool), np.full(self.num_envs, -1), nothing
        )

    def _copy_seeds(self, seed) -> list[int | None]:
        if _is_seed(seed):
            return [None if seed is None else int(seed) + copy for copy in range(self.num_envs)]
        seeds = list(seed) if isinstance(seed, (list, tuple)) else []
        if len(seeds) != self.num_envs or not all(_is_seed(item) for item in seeds):
            raise ValueError(
                f"seed of {type(self).__name__}.reset must be None, an int >= 0 or a list of {self.num_envs} "
                f"such seeds (one per sub-env), got {seed!r}"
            )
        return [None if item is None else int(item) for item in seeds]

    def _reset_copies(self, copies: np.ndarray) -> StaticGeometry:
        """Start a new episode in each of ``copies`` from its own generator; the static geometry of those copies."""
        owner, geometries = type(self).__name__, []
        for copy in copies.tolist():
            if copy == 0 and self._view is not None:
                self._view.restart(self._np_randoms[0])
            scenario, prior, odometry_rng, measurement_rng = start_episode(self.config, self._np_randoms[copy], owner)
            x, P = prior.state()
            if self._x is None or len(copies) == self.num_envs and copy == 0:
                self._x, self._P = np.zeros((self.num_envs, len(x))), np.zeros((self.num_envs, len(x), len(x)))
            if len(x) != self._x.shape[1]:
                raise ValueError(
                    f"sub-env {copy} of {owner}: with mapping=True every copy needs the same number of landmarks; "
                    f"scenario {scenario.name!r} has {len(scenario.landmarks)}, the other copies "
                    f"{(self._x.shape[1] - 3) // 2}"
                )
            self._worlds.reset_copy(copy, scenario)
            self._odometry_noise.restart(copy, odometry_rng)
            self._measurement_noise.restart(copy, measurement_rng)
            self._x[copy], self._P[copy] = x, P
            n_landmarks = len(scenario.landmarks)
            self._landmarks[copy] = 0.0
            self._landmarks[copy, :n_landmarks] = scenario.landmarks
            self._exists[copy] = np.arange(self.config["n_candidates"]) < n_landmarks
            geometries.append(StaticGeometry.from_scenario(scenario, self._worlds.wall_thickness_m))
        self._elapsed[copies] = 0
        return StaticGeometry.stack(geometries)

    def step(self, actions):
        """Act in every sub-env, with ``autoreset_mode``'s resets (see the class).

        Raises:
            ValueError: for actions that are not N integers of the action space, or, with
                ``invalid_action="raise"``, a masked action (each naming its sub-env).
        """
        if self._decision is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before step()")
        actions = self._checked_actions(actions)
        resetting = self._prev_done.copy()
        acting = ~resetting
        if self._view is not None and acting[0]:
            self._view.step(int(actions[0]))
        chosen = self._chosen_actions(actions, acting)
        rewards = self._observe(chosen)
        stepped = np.flatnonzero(acting)
        self._elapsed[stepped] += 1
        self._advance(stepped)
        truncated = acting & (self._elapsed >= self.config["horizon"])
        terminated = np.zeros(self.num_envs, dtype=bool)
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            if resetting.any():
                self._geometry = self._geometry.with_copies(
                    np.flatnonzero(resetting), self._reset_copies(np.flatnonzero(resetting))
                )
            observation, info = self._outputs(np.arange(self.num_envs), self._geometry, acting, chosen, rewards)
            self._prev_done = truncated
            return observation, rewards, terminated, truncated, info
        everyone = np.arange(self.num_envs)
        observation, info = self._outputs(everyone, self._geometry, acting, chosen, rewards)
        ended = np.flatnonzero(truncated)
        if ended.size:
            final_infos = final_step_infos(observation, info, truncated)
            geometry = self._reset_copies(ended)
            self._geometry = self._geometry.with_copies(ended, geometry)
            reset_observation, reset_info = self._outputs(
                ended, geometry, np.zeros(ended.size, dtype=bool), np.full(ended.size, -1), np.zeros(ended.size)
            )
            observation[ended] = reset_observation
            set_rows(info, ended, reset_info)
            info.update(final_infos)
        return observation, rewards, terminated, truncated, info

    def _checked_actions(self, actions) -> np.ndarray:
        array = np.asarray(actions)
        n_candidates = self.config["n_candidates"]
        if array.shape != (self.num_envs,) or array.dtype.kind not in "iu":
            raise ValueError(
                f"actions of {type(self).__name__} must be an integer array of shape ({self.num_envs},), one "
                f"per sub-env, in [0, {n_candidates - 1}]; got {array.dtype} of shape {array.shape}"
            )
        outside = np.flatnonzero((array < 0) | (array >= n_candidates))
        if outside.size:
            copy = int(outside[0])
            raise ValueError(
                f"action {array[copy]} of sub-env {copy} is not in the action space {self.single_action_space}: "
                f"expected an integer in [0, {n_candidates - 1}]"
            )
        return array.astype(int)

    def _chosen_actions(self, actions: np.ndarray, acting: np.ndarray) -> np.ndarray:
        """The landmark each acting sub-env observes, -1 for a no-op (``invalid_action`` per sub-env)."""
        mask = self._decision.action_mask
        valid = acting & mask[np.arange(self.num_envs), actions].astype(bool)
        for copy in np.flatnonzero(acting & ~valid).tolist():
            accepts_action(
                int(actions[copy]), mask[copy], self.config["invalid_action"], 'info["action_mask"]', f"sub-env {copy}"
            )
        return np.where(valid, actions, -1)

    def _observe(self, chosen: np.ndarray) -> np.ndarray:
        """Update each observing copy's EKF with a noisy measurement of its chosen landmark; the realized MI (N,)."""
        decision = self._decision
        observed, predicted, H, R = batched.select_candidates(chosen, decision.predicted, decision.H, decision.R)
        rewards = np.zeros(self.num_envs)
        observers = np.flatnonzero(observed)
        if not observers.size:
            return rewards
        measurements = np.zeros((self.num_envs, 2))
        landmarks = self._landmarks[observers, chosen[observers]]
        noise = self._measurement_noise.take(observers)
        measurements[observers] = self._sensor.measure_with_noise(self._worlds.poses[observers, 0], landmarks, noise)
        self._x, self._P = batched.range_bearing_update(
            self._x, self._P, measurements, predicted, H, R, observed, check_input=False
        )
        posterior_log_dets = np.linalg.slogdet(self._P[observers])[1]
        rewards[observers] = 0.5 * (decision.prior_log_det[observers] - posterior_log_dets)
        return rewards

    def _advance(self, copies: np.ndarray) -> None:
        """Step the worlds of ``copies`` and predict their EKFs from noisy odometry."""
        if not copies.size:
            return
        dt = self.config["time_step_s"]
        controls = self._worlds.step(dt, copies)[:, 0]
        readings = self._odometry.measure_with_noise(controls, self._odometry_noise.take(copies))
        self._x[copies], self._P[copies] = batched.predict_pose(
            self._x[copies], self._P[copies], readings, dt, self._odometry_covariance, check_input=False
        )

    def _outputs(self, copies, geometry, stepped, chosen, rewards) -> tuple[np.ndarray, dict]:
        """Decide again at the priors of ``copies`` (geometry: theirs); their observations and infos."""
        true_poses, x, P = self._worlds.poses[copies, 0], self._x[copies], self._P[copies]
        exists = self._exists[copies]
        decision = BatchedDecision.at_prior(
            self._sensor, geometry, true_poses, x, P, self._landmarks[copies], exists, self.config["mapping"]
        )
        if len(copies) == self.num_envs:
            self._decision = decision
        else:
            self._decision = BatchedDecision(
                *(set_rows(full, copies, part) for full, part in zip(self._decision, decision))
            )
        elapsed = self._elapsed[copies]
        observation = batched_observation(decision, x, P, elapsed, exists, self.config, self.single_observation_space)
        info = batched_info(decision, x, true_poses, elapsed, stepped, chosen, rewards, self.config)
        return observation, info

    def action_masks(self) -> np.ndarray:
        """The valid actions of each sub-env as bool (N, K); all ``True`` where none is valid (each is the no-op)."""
        if self._decision is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before action_masks()")
        mask = self._decision.action_mask.astype(bool)
        mask[~mask.any(axis=1)] = True
        return mask

    def render(self):
        """Sub-env 0's frame as its single env draws it (an RGB array for ``"rgb_array"``); None without a mode."""
        if self._view is None:
            gym.logger.warn(f'{type(self).__name__}.render() called without a render_mode; use render_mode="rgb_array"')
            return None
        if self._decision is None:
            raise RuntimeError(f"{type(self).__name__}: call reset() before render()")
        return self._view.render()

    def close_extras(self, **kwargs) -> None:
        self._decision = None
        if self._view is not None:
            self._view.close()


def _is_seed(value) -> bool:
    """Whether ``value`` is a seed of one sub-env: None, or an int >= 0 (not a bool)."""
    return value is None or (isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 0)
