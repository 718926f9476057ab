"""Evaluation episodes as Ray tasks: one ``EpisodeRunner`` actor per worker, results in task order."""

from __future__ import annotations

from collections.abc import Iterator, Sequence

from agents.ray_support import local_or_cluster_ray
from infonav_gym.experiments.episode_pool import EpisodeRunner


def played_on_ray(setup: tuple, tasks: Sequence[tuple[str, int]], workers: int, address: str | None) -> Iterator[dict]:
    """The metrics of every ``(agent, seed)`` task, played by ``workers`` Ray actors built from ``setup``.

    Args:
        setup: ``EpisodeRunner``'s ``(env_id, env_kwargs, agent_names)``.
        tasks: ``(agent name, seed)`` pairs.
        workers: actors (one CPU each).
        address: a Ray cluster's address, or None for a local Ray started and stopped here.
    """
    with local_or_cluster_ray(address) as ray:
        remote_runner = ray.remote(num_cpus=1)(EpisodeRunner)
        actors = [remote_runner.remote(*setup) for _ in range(workers)]
        from ray.util import ActorPool

        pool = ActorPool(actors)
        yield from pool.map(lambda actor, task: actor.play.remote(task), list(tasks))
