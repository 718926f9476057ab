"""``InfoNavParallelEnv``: the fixed reset/step cycle of a PettingZoo team env still written twice, and its hooks.

A team env written once (``cooperative_localization_v0``) has no such class: its PettingZoo env is the N = 1 view
of its vector env (``multi.parallel_view``). ``cooperative_exploration_v0`` is still on this base.

The parallel counterpart of ``infonav_gym.envs.base.InfoNavEnv``, with the same ``Decision``,
action checks (``discrete_action_index``, ``accepts_action``) and rendering. Robot ``k`` is agent
``possible_agents[k]``; every live agent acts every step, and all end together: terminated when the
optional hook ``_is_terminated`` says so, else truncated after ``max_cycles`` steps. Subclasses never
override ``reset`` or ``step``; they implement the declared hooks ``_reset_episode``, ``_next_decision``,
``_apply_actions``, ``_advance``, ``_observations``, ``_infos`` and ``_scene_frame``, and set
``possible_agents``, ``max_cycles``, ``traits`` (with its ``noop_action``) and one ``Discrete`` space
per agent (``action_space(agent)``) in ``__init__``. One step runs::

    actions -> validate (decision.action_mask) -> _apply_actions(actions, decision) -> _advance()
    -> decision = _next_decision() -> _observations(), _infos()
"""

from __future__ import annotations

import abc

import numpy as np
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec_wrapper
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from infonav_gym.envs.base import Decision, SceneRendering, accepts_action, discrete_action_index
from infonav_gym.envs.traits import EnvTraits


def team_metadata(name: str) -> dict:
    """A fresh ``metadata`` dict of a team env named ``name`` (its versioned module's name)."""
    return {"name": name, "render_modes": ["human", "rgb_array"], "render_fps": 10, "is_parallelizable": True}


def pettingzoo_entry_points(env_class) -> tuple:
    """The versioned module's ``(parallel_env, raw_env, env)`` of a team env class, as PettingZoo's envs have them.

    ``parallel_env(render_mode=None, **config)`` is the env itself; ``raw_env`` its AEC conversion; ``env``
    the AEC env with PettingZoo's order-enforcing wrapper (the one to use for turn-based code).
    """

    def parallel_env(render_mode: str | None = None, **config):
        """The parallel env: every robot acts at every step."""
        return env_class(render_mode=render_mode, **config)

    def raw_env(render_mode: str | None = None, **config) -> parallel_to_aec_wrapper:
        """The AEC (agent-by-agent) conversion of ``parallel_env``, without wrappers."""
        return parallel_to_aec_wrapper(parallel_env(render_mode=render_mode, **config))

    def env(render_mode: str | None = None, **config) -> OrderEnforcingWrapper:
        """The AEC env, wrapped to enforce PettingZoo's call order."""
        return OrderEnforcingWrapper(raw_env(render_mode=render_mode, **config))

    return parallel_env, raw_env, env


class InfoNavParallelEnv(SceneRendering, ParallelEnv):
    """Base of the multi-robot envs: seeding, action validation, truncation at ``max_cycles``, rendering.

    Attributes set by the base: ``agents`` (live agents), ``_elapsed_steps``, ``_decision`` (the current
    ``Decision``, arrays per robot and action), ``_chosen`` (each robot's executed action, ``noop_action``
    for a masked one) and ``_invalid`` (whether each robot's action was masked).
    """

    traits: EnvTraits  # ``traits.noop_action``: the action that does nothing, always valid; a masked action becomes it

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode; ``seed`` re-seeds ``np_random`` (else it continues); ``options`` are unused.

        Do not override: fill ``_reset_episode``.
        """
        if seed is not None or self.np_random is None:
            self.np_random, _ = seeding.np_random(seed)
        n = len(self.possible_agents)
        self.agents = list(self.possible_agents)
        self._elapsed_steps = 0
        self._chosen = np.full(n, self.traits.noop_action)
        self._invalid = np.zeros(n, dtype=bool)
        self._reset_episode()
        self._decision = self._next_decision().frozen()
        observations, infos = self._observations(), self._infos()
        if self.render_mode == "human":
            self.render()
        return observations, infos

    def step(self, actions: dict):
        """Check every agent's action, act on the current decision, advance time, decide again. Do not override.

        Raises:
            ValueError: for a dict that does not name every live agent once, an action outside its
                agent's space, or a masked one with ``invalid_action="raise"``; the env is left unchanged.
        """
        if not self.agents:
            raise RuntimeError(f"{type(self).__name__}: call reset() before step() (and after the episode ends)")
        decision = self._decision
        self._chosen, self._invalid = self._validated_actions(actions, decision.action_mask)
        rewards = self._apply_actions(self._chosen, decision)
        self._elapsed_steps += 1
        self._advance()
        self._decision = self._next_decision().frozen()
        observations, infos = self._observations(), self._infos()
        terminated = self._is_terminated()
        truncated = not terminated and self._elapsed_steps >= self.max_cycles
        terminations = dict.fromkeys(self.agents, terminated)
        truncations = dict.fromkeys(self.agents, truncated)
        if terminated or truncated:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return observations, dict(zip(self.possible_agents, map(float, rewards))), terminations, truncations, infos

    def _validated_actions(self, actions: dict, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every agent's action as an index (masked ones become ``noop_action``) and which were masked."""
        if not isinstance(actions, dict) or set(actions) != set(self.agents):
            given = sorted(actions) if isinstance(actions, dict) else actions
            raise ValueError(f"actions must be a dict with one action per live agent {self.agents}, got {given!r}")
        chosen = np.full(len(self.possible_agents), self.traits.noop_action)
        invalid = np.zeros(len(self.possible_agents), dtype=bool)
        mode = self.config["invalid_action"]
        for robot, agent in enumerate(self.possible_agents):
            action = discrete_action_index(actions[agent], self.action_space(agent), agent)
            if accepts_action(action, mask[robot], mode, f"infos[{agent!r}]['action_mask']", agent):
                chosen[robot] = action
            else:
                invalid[robot] = True
        return chosen, invalid

    def _decision_info(self, robot: int) -> dict:
        """The info keys every team env gives robot ``robot``: its mask, gains, reward terms and executed action."""
        decision = self._decision
        return {
            "action_mask": decision.action_mask[robot].copy(),
            "action_information_gain": decision.action_information_gain[robot].copy(),
            "reward_terms": dict(self._reward_terms[robot]),
            "chosen_action": int(self._chosen[robot]),
            "invalid_action": bool(self._invalid[robot]),
            "gps_available": bool(self._gps_available[robot]),
        }

    # ------------------------------------------------------------------ the hooks

    @abc.abstractmethod
    def _reset_episode(self) -> None:
        """Hook: start a new episode (world, generators, estimator), drawing only from ``self.np_random``.

        Called by ``reset`` after seeding, with every agent live and ``_elapsed_steps == 0``.
        """

    @abc.abstractmethod
    def _next_decision(self) -> Decision:
        """Hook: the ``Decision`` for the next actions, ``(N, n)`` arrays, one row per robot.

        Called after ``_reset_episode`` or ``_advance``; must not change the env's state (what acting
        needs goes into ``Decision.payload``).
        """

    @abc.abstractmethod
    def _apply_actions(self, actions: np.ndarray, decision: Decision) -> np.ndarray:
        """Hook: act on ``decision`` with every robot's action (N,) (valid ones; masked ones are ``noop_action``).

        May change the env's state; ``_elapsed_steps`` still counts the steps before this one.

        Returns:
            Each robot's reward (N,).
        """

    @abc.abstractmethod
    def _advance(self) -> None:
        """Hook: move time on by one step after ``_apply_actions`` (``_elapsed_steps`` already counts it)."""

    def _is_terminated(self) -> bool:
        """Optional hook: whether the episode has ended for the whole team (after ``_next_decision``); read-only.

        The default never ends it: all agents are truncated after ``max_cycles`` steps.
        """
        return False

    @abc.abstractmethod
    def _observations(self) -> dict:
        """Hook: ``{agent: observation}`` of the live agents, after the decision is set; must not change the env."""

    @abc.abstractmethod
    def _infos(self) -> dict:
        """Hook: ``{agent: info}`` of the live agents, with the keys ``action_mask``,
        ``action_information_gain``, ``reward_terms``, ``chosen_action`` and ``invalid_action``; read-only."""
