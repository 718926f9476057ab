"""Evaluation episodes played by one process, a pool of worker processes, or Ray tasks, with the same results.
Workers build their ``EpisodeRunner`` once; they are forked while torch is not imported (else from a preloaded
fork server, else spawned), get tasks as they need them and ignore Ctrl-C: the parent kills them."""

from __future__ import annotations

import collections
import multiprocessing
import signal
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from functools import partial

from infonav_gym.envs.traits import episode_metrics_of, traits_of
from infonav_gym.experiments.arguments import SEED_LIMIT
from infonav_gym.experiments.episodes import episode_infos, make_agent, make_team_agents, parallel_episode_infos
from infonav_gym.memory import check_memory
from infonav_gym.registry import PARALLEL, api_of, make_env

FORKSERVER_PRELOAD = ["infonav_gym.experiments.evaluation", "infonav_gym.envs"]  # the harness, the single envs
_worker_runner = None  # a pool worker's EpisodeRunner, built once by _start_worker
# Measured (Linux, CPython 3.11): peak RSS per episode record of `evaluate --json --output` on the env with the most
# metrics (cooperative_exploration_v0), and the largest worker Pss (from the fork server with a ppo:PATH agent).
RECORD_BYTES = 1_834  # an episode's record, per agent
WORKER_BYTES = 333_000_000  # a worker process
TASKS_PER_WORKER = 2  # tasks handed out ahead per worker: one playing, one waiting


class EpisodeRunner:
    """An env and one agent (or one per robot) per name of ``agent_names``, playing seeded episodes."""

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


def seeds_of(seed: int, episodes: int) -> range:
    """The seeds ``seed .. seed + episodes - 1`` of a run, refused where they would pass ``SEED_LIMIT - 1``."""
    check_positive(episodes, "episodes")
    if seed + episodes > SEED_LIMIT:
        raise ValueError(
            f"--seed {seed} and --episodes {episodes} would play seeds up to {seed + episodes - 1}, past the last "
            f"seed {SEED_LIMIT - 1} (2**32 - 1): lower --seed or --episodes"
        )
    return range(seed, seed + episodes)


def checked_workers(workers: int, tasks: int, records: int, what: str) -> int:
    """``workers`` capped at the ``tasks`` to play (said on stderr), once the run's memory (``records`` episode
    records, the worker processes) is checked against the available memory; ``what`` names the records."""
    capped = min(check_positive(workers, "workers"), tasks)
    check_memory(records * RECORD_BYTES + (capped if capped > 1 else 0) * WORKER_BYTES, f"{what} on {capped} worker(s)")
    if capped < workers:
        print(f"--workers {workers} capped at {capped}: there are {tasks} episodes to play", file=sys.stderr)
    return capped


def played(
    runner: EpisodeRunner,
    tasks: Iterable[tuple[str, int]],
    workers: int = 1,
    use_ray: bool = False,
    address: str | None = None,
) -> Iterator[dict]:
    """The metrics of every ``(agent, seed)`` task, in task order, as played by ``runner`` itself (``workers == 1``),
    ``workers`` processes or Ray tasks (``use_ray``, on a local Ray or the cluster at ``address``)."""
    check_positive(workers, "workers")
    if use_ray:  # one EpisodeRunner actor per worker (one CPU each)
        from agents.ray_support import local_or_cluster_ray

        with local_or_cluster_ray(address) as ray:
            from ray.util import ActorPool

            remote_runner = ray.remote(num_cpus=1)(EpisodeRunner)
            actors = ActorPool([remote_runner.remote(*runner.setup) for _ in range(workers)])
            yield from _in_order(partial(actors.submit, _remote_play), lambda _: actors.get_next(), tasks, workers)
        return
    if workers == 1:
        yield from map(runner.play, tasks)
        return
    context = multiprocessing.get_context(_start_method())
    if context.get_start_method() == "forkserver":
        context.set_forkserver_preload(FORKSERVER_PRELOAD)  # imported once by the server, its workers fork from it
    pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_start_worker, initargs=runner.setup)
    finished = False
    try:
        yield from _in_order(lambda task: pool.submit(_play, task), Future.result, tasks, workers)
        finished = True
    finally:
        _stop(pool, finished)


def _in_order(submit: Callable, result: Callable, tasks: Iterable, workers: int) -> Iterator:
    """``result(submit(task))`` of each task in order, at most ``TASKS_PER_WORKER * workers`` pending."""
    submitted = collections.deque()
    for task in tasks:
        submitted.append(submit(task))
        if len(submitted) == TASKS_PER_WORKER * workers:
            yield result(submitted.popleft())
    while submitted:
        yield result(submitted.popleft())


def _stop(pool: ProcessPoolExecutor, finished: bool) -> None:
    """Shut ``pool`` down; unless its tasks ``finished``, kill its workers rather than wait for them."""
    workers = list((pool._processes or {}).values()) if not finished else []
    for worker in workers:
        worker.kill()
    pool.shutdown(wait=True, cancel_futures=True)


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


def _remote_play(actor, task: tuple[str, int]):
    return actor.play.remote(task)
