"""``ParallelEnvView``: the PettingZoo ``ParallelEnv`` of a team env, the driver at N = 1 without autoreset.

``class MyTeamEnv(ParallelEnvView, vector_env=MyTeamVectorEnv)``: row 0 of every output as dicts per agent (one-number
infos as Python scalars). All agents end together and leave ``agents`` then (PettingZoo's semantics).
"""

from __future__ import annotations

import numpy as np
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec_wrapper
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from infonav_gym.envs.base import accepts_action, discrete_action_index
from infonav_gym.envs.copy_view import OneCopyView
from infonav_gym.envs.driver import Driver


def team_metadata(name: str) -> dict:
    """A fresh ``metadata`` dict of a team env named ``name`` (its versioned module's name)."""
    return {"name": name, "render_modes": ["human", "rgb_array"], "render_fps": 10, "is_parallelizable": True}


def pettingzoo_entry_points(env_class) -> tuple:
    """The versioned module's ``(parallel_env, raw_env, env)`` of a team env class, as PettingZoo's envs have them."""

    def parallel_env(render_mode: str | None = None, **config):
        """The parallel env (``**config``: any key of ``default_config()``): every robot acts at every step."""
        return env_class(render_mode=render_mode, **config)

    def raw_env(render_mode: str | None = None, **config) -> TeamAECEnv:
        """The AEC (agent-by-agent) conversion of ``parallel_env``, without wrappers."""
        return TeamAECEnv(parallel_env(render_mode=render_mode, **config))

    def env(render_mode: str | None = None, **config) -> OrderEnforcingWrapper:
        """The AEC env with PettingZoo's order-enforcing wrapper (the one for turn-based code)."""
        return OrderEnforcingWrapper(raw_env(render_mode=render_mode, **config))

    return parallel_env, raw_env, env


def first_copy_infos(info: dict, agents: list[str], team_keys) -> dict:
    """Copy 0's ``{agent: info}`` from a team vector env's info: row ``(0, robot)`` of each key (``team_keys``: row
    0), one-number values as Python scalars, nested dicts alike; ``_key`` masks left out."""
    infos = {agent: {} for agent in agents}
    for key, value in info.items():
        if key[0] == "_":
            continue
        if type(value) is dict:
            column = first_copy_infos(value, agents, ()).values()
        elif key in team_keys:
            column = [value.item(0) if value.ndim == 1 else value[0]] * len(agents)
        else:  # (N, R) numbers become Python scalars; (N, R, ...) arrays one row per robot
            column = value[0].tolist() if value.ndim == 2 else value[0]
        for agent_info, item in zip(infos.values(), column):
            agent_info[key] = item
    return infos


class TeamCycles:
    """A team vector env's ``max_cycles``, PettingZoo's name of its driver's ``horizon``: ``class
    MyTeamVectorEnv(TeamCycles, Driver, scenario=...)``."""

    horizon: int

    @property
    def max_cycles(self) -> int:
        """Every copy's episode length [steps], the driver's ``horizon``; settable (``set_attr``)."""
        return self.horizon

    @max_cycles.setter
    def max_cycles(self, value: int) -> None:
        self.horizon = value


class ParallelEnvView(OneCopyView, ParallelEnv):
    """One copy of ``vector_env`` (``vector``) as a PettingZoo ``ParallelEnv``."""

    vector_env: type[Driver]
    metadata_keys = ("name", "render_modes", "render_fps", "is_parallelizable")

    def __init__(self, render_mode: str | None = None, **config):
        self._view_one_copy(render_mode, config)
        vector = self.vector
        self.max_cycles = vector.max_cycles
        self.possible_agents = list(vector.agents)
        self.agents = []
        self._observation_spaces = dict.fromkeys(self.possible_agents, vector.single_observation_space)
        self._action_spaces = dict.fromkeys(self.possible_agents, vector.single_action_space)
        self.np_random = None

    def observation_space(self, agent: str):
        return self._observation_spaces[agent]

    def action_space(self, agent: str):
        return self._action_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode; ``seed`` re-seeds ``np_random`` (else it continues); ``options`` are unused."""
        if seed is not None or self.np_random is None:
            self.np_random, _ = seeding.np_random(seed)
        self.vector.use_generator(0, self.np_random)
        self.agents = list(self.possible_agents)
        observations, info = self.vector.reset()
        return self._per_agent(observations), first_copy_infos(info, self.agents, self.vector.team_info_keys)

    def step(self, actions: dict):
        """Every live agent acts; all are removed from ``agents`` when the episode ends.

        Raises:
            RuntimeError: before ``reset()`` or after the episode ended.
            ValueError: for a dict that does not name every live agent once, an action outside its agent's space,
                or a masked one with ``invalid_action="raise"``; the env is left unchanged.
        """
        if not self.agents:
            raise RuntimeError(f"{type(self).__name__}: call reset() before step() (and after the episode ends)")
        if not isinstance(actions, dict) or set(actions) != set(self.agents):
            given = sorted(actions) if isinstance(actions, dict) else actions
            raise ValueError(f"actions must be a dict with one action per live agent {self.agents}, got {given!r}")
        masks = self.vector.decision.action_mask[0]  # int8 (R, A), 1 = valid
        chosen = [self.checked_action(agent, actions[agent], masks[robot]) for robot, agent in enumerate(self.agents)]
        observations, rewards, terminated, truncated, info = self.vector.step(np.array([chosen]))
        agents = self.agents
        outputs = (
            self._per_agent(observations),
            dict(zip(agents, rewards[0].tolist())),
            dict.fromkeys(agents, bool(terminated[0, 0])),
            dict.fromkeys(agents, bool(truncated[0, 0])),
            first_copy_infos(info, agents, self.vector.team_info_keys),
        )
        if terminated[0, 0] or truncated[0, 0]:
            self.agents = []
        return outputs

    def checked_action(self, agent: str, action, mask: np.ndarray | None = None) -> int:
        """``agent``'s action as an int, checked against its space and, with ``invalid_action="raise"``, its ``mask``
        (int8, 1 = valid; default: its info's) (``ValueError`` naming ``agent``, see ``accepts_action``)."""
        index = discrete_action_index(action, self.action_space(agent), agent)
        if mask is None:
            mask = self.vector.decision.action_mask[0, self.possible_agents.index(agent)]
        accepts_action(index, mask, self.vector.config["invalid_action"], f"infos[{agent!r}]['action_mask']", agent)
        return index

    def _per_agent(self, observations: np.ndarray) -> dict:
        return {agent: observations[0, robot] for robot, agent in enumerate(self.agents)}


class TeamAECEnv(parallel_to_aec_wrapper):
    """The AEC conversion of a team env: an action is checked at the ``step`` that gives it, naming its agent
    (PettingZoo's conversion would hold it until the last agent acts)."""

    def step(self, action):
        agent = self.agent_selection
        if not (self.terminations[agent] or self.truncations[agent]):
            self.env.checked_action(agent, action)
        super().step(action)
