"""``SingleEnvView``: the Gymnasium ``Env`` of an env, the driver with one copy and no autoreset
(``class MyEnv(SingleEnvView, vector_env=MyVectorEnv)``). It hands one action on as a batch of one and returns row 0
of every output, its info as the single env's dict (masked keys left out; the reward terms in
``info["reward_terms"]``)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from infonav_gym.envs.base import discrete_action_index
from infonav_gym.envs.copy_view import OneCopyView
from infonav_gym.envs.driver import Driver
from infonav_gym.envs.vector_infos import grouped_reward_terms


def first_row(info: dict) -> dict:
    """Sub-env 0's info from a vector info: each key's row 0 where its ``_key`` mask holds, 0-d values as Python
    scalars, nested dicts alike."""
    row = {}
    for key, value in info.items():
        if key[0] == "_":
            continue
        mask = info.get("_" + key)
        if mask is not None and not mask[0]:
            continue
        if type(value) is dict:
            row[key] = first_row(value)
        else:  # an array: a 1-d one's row 0 as a Python scalar (or the object it holds), else a view of row 0
            row[key] = value.item(0) if value.ndim == 1 else value[0]
    return row


class SingleEnvView(OneCopyView, gym.Env):
    """One copy of ``vector_env``: its config keys, spaces, metrics, traits and rendering; the step of a single env.

    Stepping on after an episode ended goes on from the last state (no autoreset), as any Gymnasium env; call
    ``reset()`` to start again. ``vector`` is the underlying vector env of one copy.
    """

    vector_env: type[Driver]

    def __init__(self, render_mode: str | None = None, **config):
        self._view_one_copy(render_mode, config)
        self.observation_space = self.vector.single_observation_space
        self.action_space = self.vector.single_action_space

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode: seed ``np_random`` (Gymnasium's rule), then the copy's episode from it.

        Raises:
            ValueError: for any options.
        """
        if options:
            raise ValueError(f"{type(self).__name__}.reset takes no options, got {sorted(options)}")
        super().reset(seed=seed)
        self.vector.use_generator(0, self.np_random)
        observations, info = self.vector.reset()
        return observations[0], grouped_reward_terms(first_row(info))

    def step(self, action):
        """Act with ``action`` (one integer of the action space).

        Raises:
            ValueError: for an action outside the action space, or a masked one with ``invalid_action="raise"``.
            RuntimeError: before the first ``reset`` (the copy's).
        """
        actions = np.array([discrete_action_index(action, self.action_space)])
        observations, rewards, terminated, truncated, info = self.vector.step(actions)
        info = grouped_reward_terms(first_row(info))
        return observations[0], float(rewards[0]), bool(terminated[0]), bool(truncated[0]), info

    def action_masks(self) -> np.ndarray:
        """The valid actions now, as bool (n,), for ``MaskablePPO``: all ``True`` when none is (each is the no-op).

        Found through Gymnasium wrappers with ``env.get_wrapper_attr("action_masks")()``; before ``reset`` a
        ``RuntimeError`` (the copy's).
        """
        return self.vector.action_masks()[0]
