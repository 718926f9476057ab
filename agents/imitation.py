"""Planning amortized into a policy: behaviour cloning of the look-ahead planner, PPO's warm start
(``infonav train --init-from-planner``)."""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
from tqdm.auto import tqdm

from agents.planner import PlannerAgent, planner_settings
from infonav_gym.envs.joint_view import REWARDS_KEY
from infonav_gym.registry import PARALLEL, api_of, make_env

DEMONSTRATIONS_FILE = "demonstrations.npz"  # what ``train`` saves beside the model, to clone from again
ZIP_MAGIC = b"PK\x03\x04"  # how an .npz file starts
DEMONSTRATION_SEEDS = 1_000_000  # ``train`` plays the planner from this seed on: not the fields evaluations play


class Demonstrations(NamedTuple):
    """The planner's decisions, one row per robot and step: ``observations`` (M, D) float32, ``action_masks`` (M, A)
    bool, ``actions`` (M,) int, ``returns`` (M,) discounted from that step on, and the episodes' ``seeds`` (E,)."""

    observations: np.ndarray
    action_masks: np.ndarray
    actions: np.ndarray
    returns: np.ndarray
    seeds: np.ndarray

    @classmethod
    def joined(cls, parts: list[Demonstrations]) -> Demonstrations:
        """The rows of ``parts`` one after another."""
        return cls(*(np.concatenate([getattr(part, field) for part in parts]) for field in cls._fields))

    @classmethod
    def of_dataset(cls, dataset, team: bool, gamma: float) -> Demonstrations:
        """The decisions of every episode of a Minari ``dataset`` of ``infonav dataset`` (``team``: recorded through a
        team env's ``JointTeamEnv``, one row per robot and step), returns discounted by ``gamma``."""
        seeds = [metadata["seed"] for metadata in dataset.storage.get_episode_metadata(dataset.episode_indices)]
        return cls.joined(
            [_rows(*_decisions(episode, team), gamma, seed) for episode, seed in zip(dataset.iterate_episodes(), seeds)]
        )

    def save(self, path: Path | str) -> None:
        np.savez_compressed(path, **self._asdict())

    @classmethod
    def load(cls, path: Path | str) -> Demonstrations:
        """Demonstrations saved by ``save``; ``ValueError`` in one line naming the option, the file and what it should
        be, for any file that is not such an npz."""
        zipped = None
        try:
            with Path(path).open("rb") as file:
                zipped = file.read(len(ZIP_MAGIC)) == ZIP_MAGIC
            with np.load(path, allow_pickle=False) as arrays:
                missing = [field for field in cls._fields if field not in arrays.files]
                demonstrations = None if missing else cls(*(arrays[field] for field in cls._fields))
            problem = f"it has no arrays {', '.join(missing)}" if missing else ""
            if demonstrations is not None and len({len(rows) for rows in demonstrations[:4]}) > 1:
                problem = "its arrays have unequal rows"
        except Exception as error:  # numpy, zipfile and OS errors all mean "not such a file"
            damaged = getattr(error, "strerror", None) or "a damaged .npz"  # strerror: the OS's reason
            problem = "it is not an .npz (zip) file" if zipped is False else damaged
        if problem:
            raise ValueError(
                f"--init-from-planner {str(path)!r} is not planner demonstrations ({problem}): expected the "
                f"{DEMONSTRATIONS_FILE} a run with --init-from-planner EPISODES saved, an .npz with arrays "
                f"{', '.join(cls._fields)}"
            )
        return demonstrations


def discounted_returns(rewards: np.ndarray, gamma: float) -> np.ndarray:
    """The return ``sum_k gamma^k r_{t+k}`` from every step ``t`` of each column of ``rewards`` (T, R)."""
    returns = np.zeros(np.shape(rewards), dtype=float)
    following = np.zeros(np.shape(rewards)[1:])
    for t in range(len(rewards) - 1, -1, -1):
        following = returns[t] = rewards[t] + gamma * following
    return returns


def planner_episode(
    env_id: str, seed: int, gamma: float, env_kwargs: dict | None = None, actor: Callable | None = None
) -> Demonstrations:
    """The planner's episode on ``seed`` as demonstrations, its planners reset as ``infonav evaluate`` resets them.
    ``actor(env, robot)``: an agent per robot whose actions are executed instead, the planner only labelling the
    states they lead to (DAgger's data); the rewards, and so the returns, are then theirs."""
    env = make_env(env_id, **(env_kwargs or {}))
    try:
        team = api_of(env_id) == PARALLEL
        robots = list(env.possible_agents) if team else [None]
        planners = [PlannerAgent(env, robot, **planner_settings(env_id)) for robot in robots]
        actors = [actor(env, robot) for robot in robots] if actor else planners
        observations, infos = env.reset(seed=seed)
        if not team:  # a single env as a team of one
            observations, infos = {None: observations}, {None: infos}
        for k, acting in enumerate(planners + actors):  # the planners twice without an actor: harmless
            acting.reset(seed=1000 * seed + k % len(robots) if team else seed)
        seen, masks, actions, rewards, done = [], [], [], [], False
        while not done:  # a team env ends for every robot at once
            chosen = [planner.act(observations[robot], infos[robot]) for robot, planner in zip(robots, planners)]
            seen.append([observations[robot] for robot in robots])
            masks.append([infos[robot]["action_mask"] for robot in robots])
            actions.append(chosen)
            if actor:
                chosen = [acting.act(observations[robot], infos[robot]) for robot, acting in zip(robots, actors)]
            if team:
                observations, reward, _, _, infos = env.step(dict(zip(robots, chosen)))
                done = not env.agents
            else:
                observation, reward, terminated, truncated, info = env.step(chosen[0])
                observations, reward, infos = {None: observation}, {None: reward}, {None: info}
                done = terminated or truncated
            rewards.append([reward[robot] for robot in robots])
    finally:
        env.close()

    return _rows(seen, masks, actions, rewards, gamma, seed)


def _decisions(episode, team: bool) -> tuple:
    """A Minari episode's ``(observations, action_masks, actions, rewards)``, each (T, R, ...) (R = 1 but in a team):
    the observation, mask and action of every decision and the reward it brought."""
    infos = episode.infos
    if team:
        robots = [key for key in infos if key != REWARDS_KEY]
        masks = np.stack([infos[robot]["action_mask"][:-1] for robot in robots], axis=1)
        return episode.observations[:-1], masks, episode.actions, infos[REWARDS_KEY][1:]
    steps = (episode.observations[:-1], infos["action_mask"][:-1], episode.actions, episode.rewards)
    return tuple(np.expand_dims(values, 1) for values in steps)


def _rows(observations, masks, actions, rewards, gamma: float, seed: int) -> Demonstrations:
    """One episode's decisions (T, R, ...) as demonstrations, robot by robot."""

    def rows(values, dtype):
        array = np.asarray(values, dtype=dtype)
        return np.swapaxes(array, 0, 1).reshape(-1, *array.shape[2:])

    returns = discounted_returns(np.asarray(rewards, dtype=float), gamma)
    return Demonstrations(
        rows(observations, np.float32),
        rows(masks, bool),
        rows(actions, np.int64),
        rows(returns, float),
        np.array([seed]),
    )


def planner_demonstrations(
    env_id: str,
    episodes: int,
    seed: int = 0,
    gamma: float = 0.99,
    env_kwargs: dict | None = None,
    workers: int = 1,
    progress: bool = True,
    actor: Callable | None = None,
) -> Demonstrations:
    """The planner's episodes on seeds ``seed .. seed + episodes - 1``, joined in seed order, played in ``workers``
    processes (``ValueError`` for counts below 1 or an env without a planning model); ``actor``: ``planner_episode``'s,
    picklable with ``workers`` > 1."""
    if episodes < 1 or workers < 1:
        raise ValueError(f"episodes and workers must be >= 1, got {episodes} and {workers}")
    what = "planner labels" if actor else "planner demonstrations"
    bar = tqdm(total=episodes, desc=what, unit="episode", disable=not progress)
    episode = partial(planner_episode, env_id, gamma=gamma, env_kwargs=env_kwargs, actor=actor)
    parts = []
    with bar, ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
        played = map if workers == 1 else pool.map  # spawn: fresh interpreters, no torch or numba state forked
        for part in played(episode, range(seed, seed + episodes)):
            parts.append(part)
            bar.update()
    return Demonstrations.joined(parts)


def clone_planner(
    model, demonstrations: Demonstrations, epochs: int = 50, batch_size: int = 256, learning_rate: float = 1e-3
) -> list[dict]:
    """Fit ``model``'s ``MaskablePPO`` policy to ``demonstrations``: the actor by behaviour cloning, the critic to the
    returns (loss: action NLL + half the value MSE), minibatches drawn from ``model.seed``; its ``VecNormalize`` starts
    from their observation statistics. Returns each epoch's mean ``action_nll`` and ``value_mse``; ``ValueError`` for
    demonstrations of another observation or action size."""
    expected = model.observation_space.shape, (int(model.action_space.n),)
    found = demonstrations.observations.shape[1:], demonstrations.action_masks.shape[1:]
    if found != expected:
        raise ValueError(
            f"planner demonstrations of {found[0]} observations and {found[1]} actions do not fit a model of "
            f"{expected[0]} and {expected[1]}: were they recorded on another env or config?"
        )
    normalization = model.get_vec_normalize_env()
    if normalization is not None and normalization.norm_obs:
        rows = demonstrations.observations.astype(float)
        normalization.obs_rms.mean, normalization.obs_rms.var = rows.mean(axis=0), rows.var(axis=0)
        normalization.obs_rms.count = float(len(rows))
    observations = _normalized(model, demonstrations.observations)
    columns = demonstrations._replace(observations=observations)[:4]  # observations, masks, actions, returns
    tensors = [torch.as_tensor(array) for array in columns]
    policy = model.policy
    optimizer = torch.optim.Adam(policy.parameters(), lr=learning_rate)
    order = np.random.default_rng(model.seed)
    epochs_done = []
    policy.set_training_mode(True)
    for _ in range(epochs):
        batches = np.array_split(order.permutation(len(observations)), max(len(observations) // batch_size, 1))
        losses = np.array(
            [_fitted_batch(policy, optimizer, *(tensor[batch] for tensor in tensors)) for batch in batches]
        )
        epochs_done.append(dict(zip(("action_nll", "value_mse"), losses.mean(axis=0).tolist())))
    policy.set_training_mode(False)
    return epochs_done


def _fitted_batch(policy, optimizer, observations, masks, actions, returns) -> tuple[float, float]:
    """One gradient step on a minibatch; its ``(action_nll, value_mse)`` before the step."""
    values, log_prob, _ = policy.evaluate_actions(observations.float(), actions, action_masks=masks)
    action_nll = -log_prob.mean()
    value_mse = torch.nn.functional.mse_loss(values.flatten(), returns.float())
    optimizer.zero_grad()
    (action_nll + 0.5 * value_mse).backward()
    optimizer.step()
    return action_nll.item(), value_mse.item()


def agreement(model, demonstrations: Demonstrations, normalization=None) -> float:
    """The fraction of the demonstrations' rows where ``model``'s most probable valid action is the planner's
    (``normalization``: its ``VecNormalize`` when the model has no env, as a loaded one)."""
    observations = torch.as_tensor(_normalized(model, demonstrations.observations, normalization)).float()
    with torch.no_grad():
        logits = model.policy.get_distribution(observations).distribution.logits.numpy()
    chosen = np.argmax(np.where(demonstrations.action_masks, logits, -np.inf), axis=1)
    return float(np.mean(chosen == demonstrations.actions))


def _normalized(model, observations: np.ndarray, normalization=None) -> np.ndarray:
    """``observations`` as ``model``'s policy sees them: through its ``VecNormalize`` (``normalization``, else its
    env's), if it normalizes them."""
    if normalization is None:
        normalization = model.get_vec_normalize_env()
    if normalization is None or not normalization.norm_obs:
        return observations
    return normalization.normalize_obs(observations)
