"""The scenario protocol: every env is a ``EnvScenario``, a few named functions over one explicit batched ``State``.

Modelled on the functional envs of the ecosystem (Gymnasium's ``FuncEnv``, gymnax, VMAS's ``BaseScenario``). A
scenario declares its config (``default_config``), its constants and spaces (``__init__``) and implements the hooks
below (``docs/protocol.md`` tabulates them).

A hook reads only its arguments and the scenario's constants (set in its ``__init__``). Each copy's randomness is in
the state (the noise streams drawn from its generator at ``initial``). The state's arrays have a leading copy
dimension N and, for what each robot has, an agent dimension R (1 for a single-agent env); hooks may update them in
place and return the state: the decision the action was taken at keeps what the reward needs of the prior. One
driver (``envs.driver.Driver``) runs every scenario: reset, step, autoreset, seeds, action checks, steps against the
horizon, rendering; the Gymnasium and PettingZoo envs are its views at N = 1.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import ClassVar

import gymnasium as gym
import numpy as np

from infonav_gym.compiled import CopyThreads
from infonav_gym.envs.base import shared_config
from infonav_gym.envs.traits import EnvTraits


@dataclass
class State:
    """What every scenario's state has: each copy's steps in its episode (N,), counted by the driver."""

    elapsed: np.ndarray


class EnvScenario(abc.ABC):
    """An env written once, over all copies: its constants, spaces and named functions (see the module).

    Class attributes: ``metadata`` (render modes and fps), ``episode_metrics``, ``traits``, ``team`` (a PettingZoo
    team env: actions, rewards and terminations per agent), ``horizon_key`` (the config key of the episode length)
    and ``team_info_keys`` (a team's infos of the whole team, (N,)). ``__init__`` sets ``observation_space``,
    ``action_space`` (one agent's), ``agents`` (their names) and the constants the hooks read.
    """

    metadata: ClassVar[dict] = {"render_modes": ["human", "rgb_array"], "render_fps": 10}
    episode_metrics: ClassVar[tuple] = ()
    traits: ClassVar[EnvTraits]
    team: ClassVar[bool] = False
    horizon_key: ClassVar[str] = "horizon"
    team_info_keys: ClassVar[frozenset] = frozenset()
    observation_space: gym.Space
    action_space: gym.spaces.Discrete
    agents: list[str] = ["agent"]
    threads: CopyThreads = CopyThreads()  # what runs its kernels over the copies (the driver's ``num_threads``)

    def __init__(self, config: dict, copies: int, owner: str, render_mode: str | None):
        """Check the scenario's own config keys (``owner`` names the env in errors) and set its constants."""
        self.config, self.copies, self.owner, self.drawing = config, copies, owner, render_mode is not None
        self.every_copy = np.arange(copies)  # the rows of all copies, for a step in which they all act

    @classmethod
    def default_config(cls) -> dict:
        """A fresh dict of every config key with its default; the constructor's keywords override it."""
        return shared_config()

    @classmethod
    def copy_kb(cls, config: dict) -> float:
        """The memory a copy takes at ``config`` [kB], checked before any array is allocated (``traits``)."""
        return cls.traits.kb_per_copy

    @abc.abstractmethod
    def allocate(self, copies: int) -> State:
        """The state of ``copies`` copies before their first episode."""

    @abc.abstractmethod
    def initial(self, state: State, rows: np.ndarray, rngs: list[np.random.Generator]) -> State:
        """Start an episode in each copy of ``rows`` (ascending; their ``elapsed`` is 0) from its generator."""

    @abc.abstractmethod
    def decision(self, state: State, rows):
        """The decision (a named tuple with ``action_mask`` and ``action_information_gain``) of the copies ``rows``
        (a slice of all, or their indices) at their priors."""

    @abc.abstractmethod
    def transition(self, state: State, decision, action: np.ndarray, acting: np.ndarray) -> State:
        """The copies ``acting`` (N,) bool take ``action`` (N, R) (-1: the no-op, for a masked action and in a copy
        not acting) at ``decision``; what the step brought stays in the state for ``reward`` and ``info``."""

    @abc.abstractmethod
    def reward(self, decision, action: np.ndarray, state: State) -> np.ndarray:
        """Each copy's reward (N,), or each robot's (N, R) for a team, of the step just taken (a new array: the
        state's may change in place)."""

    def terminal(self, state: State) -> np.ndarray:
        """Which copies ended their episode in this step (N,) bool: none, unless the scenario says otherwise."""
        return np.zeros(len(state.elapsed), dtype=bool)

    @abc.abstractmethod
    def observation(self, state: State, decision, rows) -> np.ndarray:
        """The observations of the copies ``rows`` at their ``decision``."""

    @abc.abstractmethod
    def info(self, state: State, decision, rows, stepped: np.ndarray) -> dict:
        """The infos of the copies ``rows``: arrays (n, ...), nested dicts with their ``_key`` masks (the driver adds
        the top-level ones); ``stepped`` (n,): which of them took a step (the others were just reset)."""

    def frame(self, state: State, decision):
        """Copy 0's ``infonav_gym.scene.SceneFrame`` now, to render."""
        raise NotImplementedError(f"{self.owner} does not render")
