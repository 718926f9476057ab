"""The agents an evaluation plays, by name, and their seeded episodes: what the evaluation and its worker pools
(``episode_pool``) both run."""

from __future__ import annotations

from collections.abc import Iterator

import gymnasium as gym

from agents import GreedyEntropyAgent, RandomAgent
from agents.base import env_name
from agents.everything import EverythingAgent
from agents.nearest import RANGE_KEY, NearestAgent
from agents.ray_support import DISTRIBUTED_HINT
from infonav_gym.envs.traits import EnvTraits, has_planning_model, traits_of
from infonav_gym.registry import registered_envs

AGENT_KINDS = {  # every agent name make_agent takes (NAME:ARGUMENT: a prefix and its argument), and what it is
    "random": "a valid action at random",
    "greedy": "the most expected information gain now",
    "nearest": "the reading of the nearest target, on envs whose infos give action_range_m",
    "everything": "the action that observes everything at once (every return), on envs that declare one",
    "planner": "a look-ahead planner, on envs with a planning model",
    "ppo:PATH": "a model.zip of infonav train, or its directory",
    "rllib:DIR": "a checkpoint directory of infonav train --backend rllib (the distributed extra)",
    "benchmarl:DIR": "a robot of a team env, by the actor of infonav train --backend benchmarl (the marl extra)",
}
AGENT_NAMES = tuple(AGENT_KINDS)
PPO_PREFIX = "ppo:"
RLLIB_PREFIX = "rllib:"
BENCHMARL_PREFIX = "benchmarl:"


def check_agent_name(name: str) -> None:
    """Raise ``ValueError`` unless ``name`` is one of ``AGENT_KINDS``: a plain name, or a prefix and its argument."""
    takes_argument = {kind.partition(":")[0]: ":" in kind for kind in AGENT_KINDS}
    kind, colon, argument = name.partition(":")
    if takes_argument.get(kind) == bool(colon) == bool(argument):
        return
    raise ValueError(f"unknown agent {name!r}; choose from {', '.join(AGENT_NAMES)}")


def make_agent(
    name: str, n_actions: int, noop_action: int | None = None, env: gym.Env | None = None, agent: str | None = None
):
    """A baseline agent by name; ``planner``, ``ppo:PATH``, ``rllib:DIR`` and ``benchmarl:DIR`` need the ``env`` (and in
    a PettingZoo env the robot ``agent``) they act in, and are imported only when asked for."""
    check_agent_name(name)
    if name == "random":
        return RandomAgent(n_actions, noop_action=noop_action)
    if name == "greedy":
        return GreedyEntropyAgent()
    if env is None:
        raise ValueError(f"agent {name!r} needs the env it will act in")
    if name == "nearest":
        if RANGE_KEY not in traits_of(env).info_keys:
            ranged = [
                entry.id
                for entry in registered_envs()
                if RANGE_KEY in getattr(entry.load(), "traits", EnvTraits()).info_keys
            ]
            raise ValueError(
                f"agent 'nearest' is not available for {env_name(env)}: its infos give no {RANGE_KEY}; "
                f"use it on {', '.join(ranged)}"
            )
        return NearestAgent(noop_action=noop_action or 0)
    if name == "everything":
        action = traits_of(env).everything_action
        if action is None:
            having = [
                entry.id
                for entry in registered_envs()
                if getattr(getattr(entry.load(), "traits", None), "everything_action", None) is not None
            ]
            raise ValueError(
                f"agent 'everything' is not available for {env_name(env)}: it declares no everything_action; "
                f"use it on {', '.join(having)}"
            )
        return EverythingAgent(action, noop_action=noop_action or 0)
    if name == "planner":
        if not has_planning_model(env):
            planning_env_ids = [entry.id for entry in registered_envs() if has_planning_model(entry.load())]
            raise ValueError(
                f"agent 'planner' is not available for {env_name(env)}: it declares no planning model "
                f"(no planning_model() method); use random, greedy or ppo:PATH, or the planner on "
                f"{', '.join(planning_env_ids)}"
            )
        try:
            from agents.planner import PlannerAgent, planner_settings
        except ImportError as error:
            raise ValueError(
                f"agent 'planner' is not available: agents.planner.PlannerAgent does not import ({error})"
            ) from None
        return PlannerAgent(env, agent, **planner_settings(env_name(env)))
    if name.startswith(RLLIB_PREFIX):
        try:
            from agents.rllib_agent import RLlibAgent
        except ImportError as error:
            raise ValueError(f"agent {name!r} needs Ray: {DISTRIBUTED_HINT} ({error})") from None
        return RLlibAgent(name[len(RLLIB_PREFIX) :], env, agent)
    if name.startswith(BENCHMARL_PREFIX):
        from agents.benchmarl_agent import BenchMARLAgent  # imports BenchMARL only when it builds the actor

        return BenchMARLAgent(name[len(BENCHMARL_PREFIX) :], env, agent)
    try:
        from agents.ppo import PPOAgent
    except ImportError as error:
        raise ValueError(f"agent {name!r} needs the rl extra (pip install 'infonav-gym[rl]'): {error}") from None
    return PPOAgent(name[len(PPO_PREFIX) :], env, agent)


def make_team_agents(name: str, env) -> dict:
    """One agent per robot of a PettingZoo parallel env ``env``: ``{robot: agent}`` (``ppo:PATH`` one shared policy)."""
    noop_action = traits_of(env).noop_action
    return {
        robot: make_agent(name, env.action_space(robot).n, noop_action=noop_action, env=env, agent=robot)
        for robot in env.possible_agents
    }


def episode_infos(env: gym.Env, agent, seed: int) -> Iterator[dict]:
    """The info of one seeded episode's reset, then of each of its steps, as they are played."""
    observation, info = env.reset(seed=seed)
    agent.reset(seed=seed)
    yield info
    done = False
    while not done:
        observation, _, terminated, truncated, info = env.step(agent.act(observation, info))
        yield info
        done = terminated or truncated


def robot_seed(seed: int | None, k: int) -> int | None:
    """The seed robot ``k``'s agent is reset with in an episode seeded ``seed``: ``1000 * seed + k`` (None: none)."""
    return None if seed is None else 1000 * seed + k


def parallel_episode_infos(env, agents: dict, seed: int) -> Iterator[dict]:
    """The ``{robot: info}`` of one seeded episode's reset and steps of a PettingZoo parallel env, as played (robot
    ``k``'s agent reset with ``robot_seed(seed, k)``)."""
    observations, infos = env.reset(seed=seed)
    for k, robot in enumerate(env.possible_agents):
        agents[robot].reset(seed=robot_seed(seed, k))
    yield infos
    while env.agents:
        actions = {name: agents[name].act(observations[name], infos[name]) for name in env.agents}
        observations, _, _, _, infos = env.step(actions)
        yield infos
