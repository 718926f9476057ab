"""Evaluation episodes played by one process, a pool of worker processes, or Ray tasks.

An episode's metrics are a function of the env id, its config, the agent's name and the seed alone
(``EpisodeRunner.infos`` resets the env and the agent with the seed), so each worker builds its own env and
agents once (``EpisodeRunner``) and plays the ``(agent, seed)`` tasks it is given: results equal a single
process's, seed for seed, whatever the number of workers. Results come back in task order.

Worker processes are forked on platforms that have ``fork`` while torch is not yet imported. Once it is (a
fork after torch has started its thread pool can hang) they come from a fork server that has imported the
harness and the envs once (``forkserver``, started on first use and kept for the process's later pools),
else they are spawned (each re-imports the package: about a second). Workers ignore Ctrl-C (it reaches the whole
process group): the parent stops handing out episodes and keeps the results it has.
"""

from __future__ import annotations

import multiprocessing
import signal
import sys
from collections.abc import Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor

from infonav_gym.envs.traits import episode_metrics_of, traits_of
from infonav_gym.experiments.episodes import episode_infos, make_agent, make_team_agents, parallel_episode_infos
from infonav_gym.registry import PARALLEL, api_of, make_env

FORKSERVER_PRELOAD = ["infonav_gym.experiments.evaluation", "infonav_gym.envs"]  # the harness, the single envs
_worker_runner = None  # a pool worker's EpisodeRunner, built once by _start_worker


class EpisodeRunner:
    """An env and one agent (or one per robot) per agent name, playing seeded episodes.

    Args:
        env_id: a registered env id.
        env_kwargs: its config overrides.
        agent_names: names ``episodes.make_agent`` takes (random, greedy, planner, ppo:PATH).
    """

    def __init__(self, env_id: str, env_kwargs: dict, agent_names: Sequence[str]):
        self.setup = (env_id, dict(env_kwargs), list(agent_names))  # what a worker builds its own runner from
        self.parallel = api_of(env_id) == PARALLEL
        self.env = make_env(env_id, **env_kwargs)
        try:
            if self.parallel:
                self.agents = {name: make_team_agents(name, self.env) for name in agent_names}  # {robot: agent}
            else:
                noop_action = traits_of(self.env).noop_action
                self.agents = {
                    name: make_agent(name, self.env.action_space.n, noop_action, env=self.env) for name in agent_names
                }
        except Exception:
            self.env.close()
            raise

    def play(self, task: tuple[str, int]) -> dict:
        """The env's declared ``episode_metrics`` of agent ``task[0]``'s episode on seed ``task[1]``."""
        steps = list(self.infos(task))[1:]
        return {metric.name: metric.compute(steps) for metric in episode_metrics_of(self.env)}

    def infos(self, task: tuple[str, int]):
        """The infos of agent ``task[0]``'s episode on seed ``task[1]``: the reset's, then each step's, as played."""
        name, seed = task
        return (parallel_episode_infos if self.parallel else episode_infos)(self.env, self.agents[name], seed)

    def close(self) -> None:
        self.env.close()


def check_positive(value, name: str) -> int:
    """``value`` as an int >= 1, else ``ValueError`` naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
    return value


def played(
    runner: EpisodeRunner,
    tasks: Sequence[tuple[str, int]],
    workers: int = 1,
    use_ray: bool = False,
    address: str | None = None,
) -> Iterator[dict]:
    """The metrics of every ``(agent, seed)`` task, in task order, as they are played.

    Args:
        runner: plays the tasks itself when ``workers == 1`` (and gives its env id, config and agents to the
            workers otherwise).
        tasks: ``(agent name, seed)`` pairs.
        workers: processes playing at once.
        use_ray: play them as Ray tasks (``workers`` of them at once) on a local Ray, or the cluster at
            ``address``; needs the ``distributed`` extra.

    Raises:
        ValueError: for ``workers < 1``, or ``use_ray`` without Ray installed (saying how to install it).
    """
    check_positive(workers, "workers")
    if use_ray:  # one EpisodeRunner actor per worker (one CPU each)
        from agents.ray_support import local_or_cluster_ray

        with local_or_cluster_ray(address) as ray:
            from ray.util import ActorPool

            remote_runner = ray.remote(num_cpus=1)(EpisodeRunner)
            actors = [remote_runner.remote(*runner.setup) for _ in range(workers)]
            yield from ActorPool(actors).map(lambda actor, task: actor.play.remote(task), list(tasks))
        return
    if workers == 1:
        yield from map(runner.play, tasks)
        return
    context = multiprocessing.get_context(_start_method())
    if context.get_start_method() == "forkserver":
        context.set_forkserver_preload(FORKSERVER_PRELOAD)  # imported once by the server, its workers fork from it
    with ProcessPoolExecutor(workers, mp_context=context, initializer=_start_worker, initargs=runner.setup) as pool:
        yield from pool.map(_play, tasks)  # one task at a time: on Ctrl-C only the episodes being played are waited for


def _start_method() -> str:
    """``fork`` where it exists and torch is not imported yet, else ``forkserver`` where it exists, else ``spawn``."""
    methods = multiprocessing.get_all_start_methods()
    if "fork" in methods and "torch" not in sys.modules:
        return "fork"
    return "forkserver" if "forkserver" in methods else "spawn"


def _start_worker(env_id: str, env_kwargs: dict, agent_names: Sequence[str]) -> None:
    global _worker_runner
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C reaches the whole process group: the parent handles it
    _worker_runner = EpisodeRunner(env_id, env_kwargs, agent_names)


def _play(task: tuple[str, int]) -> dict:
    return _worker_runner.play(task)
