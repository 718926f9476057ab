"""``LandmarkSelectionVectorEnv``: N copies of ``infonav/LandmarkSelection-v0`` stepped at once on stacked arrays.

``gym.make_vec("infonav/LandmarkSelection-v0", num_envs=N, **config)`` returns it. The estimation (EKF
prediction, range-bearing updates, expected gains, log-determinants) and the visibility run batched over
the copies (``estimation.batched``, ``world.visibility``), the physics in a ``WorldBatch`` (numpy free motion, a
copy's own Pymunk space for its contact steps) and the sensor noise from one stream per copy (``NoiseStreams``,
the single env's generators drawn ahead). So sub-env ``i`` after ``reset(seed=s)`` gives the numbers of
``gym.make("infonav/LandmarkSelection-v0")`` after ``reset(seed=s + i)``.
"""

from __future__ import annotations

import numpy as np

from infonav_gym.envs.landmark_selection import LandmarkSelectionEnv, start_episode
from infonav_gym.envs.landmark_selection_batch import BatchedDecision, batched_info, batched_observation
from infonav_gym.envs.one_robot_vector import OneRobotVectorEnv
from infonav_gym.envs.vector_infos import set_rows
from infonav_gym.estimation import batched
from infonav_gym.information import log_det_spd
from infonav_gym.world.visibility import StaticGeometry


class LandmarkSelectionVectorEnv(OneRobotVectorEnv, single_env=LandmarkSelectionEnv):
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

    def _allocate(self) -> None:
        num_envs = self.num_envs
        self._x = self._P = None
        self._elapsed = np.zeros(num_envs, dtype=int)
        n_candidates = self.config["n_candidates"]
        self._landmarks = np.zeros((num_envs, n_candidates, 2))
        self._exists = np.zeros((num_envs, n_candidates), dtype=bool)

    def _reset_copies(self, copies: np.ndarray) -> StaticGeometry:
        """Start a new episode in each of ``copies`` from its own generator; the static geometry of those copies."""
        owner, geometries = type(self).__name__, []
        self._view_restarts(copies)
        for copy in copies.tolist():
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
        """Act in every sub-env, with ``autoreset_mode``'s resets (see the class; errors: ``_begin_step``)."""
        acting, chosen = self._begin_step(actions)
        rewards = self._observe(chosen)
        stepped = np.flatnonzero(acting)
        self._elapsed[stepped] += 1
        self._advance(stepped)
        truncated = acting & (self._elapsed >= self.config["horizon"])
        observation, info = self._finish_step(
            truncated, lambda copies, geometry: self._outputs(copies, geometry, acting, chosen, rewards)
        )
        return observation, rewards, np.zeros(self.num_envs, dtype=bool), truncated, info

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
        posterior_log_dets = log_det_spd(self._P[observers], check_input=False)  # as the single env's
        rewards[observers] = 0.5 * (decision.prior_log_det[observers] - posterior_log_dets)
        return rewards

    def _advance(self, copies: np.ndarray) -> None:
        """Step the worlds of ``copies`` and predict their EKFs from noisy odometry."""
        if copies.size:
            self._x[copies], self._P[copies] = self._moved(copies, self._x[copies], self._P[copies])

    def _reset_outputs(self, copies: np.ndarray, geometry: StaticGeometry) -> tuple[np.ndarray, dict]:
        """The observations and reset infos of ``copies``, just reset (``geometry``: theirs)."""
        return self._outputs(
            copies, geometry, np.zeros(len(copies), dtype=bool), np.full(len(copies), -1), np.zeros(len(copies))
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
