"""``NativeVectorEnv``: what every native infonav vector env shares: its arguments, seeding and rendering.

A native vector env steps N copies of one single env (Gymnasium or PettingZoo parallel) at once on stacked
arrays; the subclass does the stepping. This base checks ``num_envs`` and ``autoreset_mode``, builds a single
env from the config (which checks it as the single env does, and gives the spaces and sensors), keeps one
generator per copy, and renders copy 0 through a ``FirstCopyView``.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv

from infonav_gym.envs.vector_infos import autoreset_mode_of, checked_num_envs, reseeded
from infonav_gym.envs.vector_view import FirstCopyView


class NativeVectorEnv(VectorEnv):
    """Base of the native vector envs: N copies of the single env a subclass names, stepped by the subclass.

    A subclass declares its single env, ``class MyVectorEnv(NativeVectorEnv, single_env=MyEnv)`` (its
    ``metadata``: the single env's render modes and fps, ``NEXT_STEP`` by default), and fills the hook
    ``_allocate(num_envs)`` (its spaces and stacked arrays). The base sets ``num_envs``, ``autoreset_mode`` (and
    ``metadata["autoreset_mode"]``), ``render_mode``, ``config`` (the checked config), ``_single`` (a single env
    without rendering, for the spaces and sensors), ``_view`` (copy 0's ``FirstCopyView`` with a ``render_mode``,
    else None), ``_np_randoms`` (None per copy until its first reset) and ``_decision`` (None until the subclass
    decides at the first reset).

    Args:
        num_envs: N, an int >= 1.
        render_mode: None, or a render mode of the single env.
        autoreset_mode: one of ``AUTORESET_MODES``: the enum, its value or its name (``"same_step"``).
        **config: the single env's config keys.

    Raises:
        ValueError: for a bad ``num_envs``, ``autoreset_mode``, ``render_mode`` or config, naming it.
    """

    AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP)
    single_env_class: type

    def __init_subclass__(cls, single_env: type | None = None, **kwargs):
        super().__init_subclass__(**kwargs)
        if single_env is not None:
            cls.single_env_class = single_env
            cls.metadata = {
                "render_modes": single_env.metadata["render_modes"],
                "render_fps": single_env.metadata["render_fps"],
                "autoreset_mode": AutoresetMode.NEXT_STEP,
            }

    def __init__(
        self,
        num_envs: int = 1,
        *,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        **config,
    ):
        owner = type(self).__name__
        checked_num_envs(num_envs, owner)
        self.autoreset_mode = autoreset_mode_of(autoreset_mode, self.AUTORESET_MODES, owner)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        single_env = self.single_env_class
        self._single = single_env(**config)  # checks the config as the single env does
        self.config = self._single.config
        self.num_envs = num_envs
        self.render_mode = render_mode
        self._view = None if render_mode is None else FirstCopyView(single_env(render_mode, **config))
        self._np_randoms: list[np.random.Generator | None] = [None] * num_envs
        self._decision = None
        self._allocate(num_envs)

    def _allocate(self, num_envs: int) -> None:
        """Hook: set the spaces (``single_observation_space`` ...) and the stacked arrays of ``num_envs`` copies."""
        raise NotImplementedError(f"{type(self).__name__} must implement _allocate(num_envs)")

    @property
    def np_randoms(self) -> list[np.random.Generator | None]:
        """Each copy's generator (its single env's ``np_random``), None before its first reset."""
        return list(self._np_randoms)

    def _reseed(self, seed, options: dict | None) -> None:
        """Seed the copies for ``reset``: an int ``s`` gives copy ``i`` the seed ``s + i``; a list one seed each.

        Raises:
            ValueError: for a seed that is not None, an int >= 0 or a list of N such seeds, or any options.
        """
        if options:
            raise ValueError(f"{type(self).__name__}.reset takes no options, got {sorted(options)}")
        self._np_randoms = reseeded(self._np_randoms, seed, type(self).__name__)

    def render(self):
        """Copy 0's frame as its single env draws it (an RGB array for ``"rgb_array"``); None without a mode."""
        owner = type(self).__name__
        if self._view is None:
            gym.logger.warn(f'{owner}.render() called without a render_mode; use render_mode="rgb_array"')
            return None
        if self._decision is None:
            raise RuntimeError(f"{owner}: call reset() before render()")
        return self._view.render()

    def close_extras(self, **kwargs) -> None:
        self._decision = None
        if self._view is not None:
            self._view.close()
