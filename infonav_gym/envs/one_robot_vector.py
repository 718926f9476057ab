"""``OneRobotVectorEnv``: the native vector envs of one robot with a range-bearing sensor and odometry.

Their copies' robots move in a ``WorldBatch``; each copy's odometry and measurement noise come from its own
streams (``NoiseStreams``, the single env's two generators drawn ahead), and the EKFs predict from the noisy
odometry on the batched core, as ``PoseEKF.predict`` does.
"""

from __future__ import annotations

import numpy as np
from gymnasium.vector import AutoresetMode

from infonav_gym.envs.noise_streams import NoiseStreams
from infonav_gym.envs.vector_base import InfoNavVectorEnv
from infonav_gym.estimation import batched
from infonav_gym.world.world_batch import WorldBatch


class OneRobotVectorEnv(InfoNavVectorEnv):
    """Base of ``LandmarkSelectionVectorEnv`` and ``ActiveLocalizationVectorEnv``; a subclass sets up its own
    stacked state in ``_allocate()`` (see ``InfoNavVectorEnv`` for the rest)."""

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **config,
    ):
        single = self._configure(num_envs, render_mode, autoreset_mode, config)
        self._sensor, self._odometry = single.sensor, single.odometry
        self._odometry_covariance = self._odometry.noise_covariance()
        self._worlds = WorldBatch(num_envs)
        self._odometry_noise, self._measurement_noise = NoiseStreams(num_envs, 2), NoiseStreams(num_envs, 2)
        self._allocate()

    def _allocate(self) -> None:
        """Hook: the subclass's stacked arrays of ``num_envs`` copies."""
        raise NotImplementedError(f"{type(self).__name__} must implement _allocate()")

    def _moved(self, copies: np.ndarray, x: np.ndarray, P: np.ndarray, commands=None):
        """Drive the robots of ``copies`` one step (``commands`` (n, 2) or their routes); their predicted ``(x, P)``."""
        dt = self.config["time_step_s"]
        controls = self._worlds.step(dt, copies, None if commands is None else commands[:, None])[:, 0]
        readings = self._odometry.measure_with_noise(controls, self._odometry_noise.take(copies))
        return batched.predict_pose(x, P, readings, dt, self._odometry_covariance, check_input=False)
