"""``infonav dataset``: any agent's episodes on any env as a local Minari dataset (the data extra), with the env's spec
so that ``MinariDataset.recover_environment()`` makes the env again.

A single-agent env is recorded as it is. A team env is recorded through its ``JointTeamEnv`` (one Gymnasium env whose
agent is the whole team): one Minari episode per team episode, each step every robot's observation and action, so a
dataset holds what the team did together (who saw what when) and recreates the team env, not one robot's view of it.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import warnings
from pathlib import Path

import gymnasium as gym
import numpy as np
from tqdm.auto import tqdm

from infonav_gym.compiled import INTERRUPTIONS, pressed_ctrl_c
from infonav_gym.envs.joint_view import joint_spec, recorded_env
from infonav_gym.envs.traits import has_planning_model, traits_of
from infonav_gym.experiments.episode_pool import seeds_of
from infonav_gym.experiments.episodes import (
    check_agent_name,
    episode_infos,
    make_agent,
    make_team_agents,
    robot_seed,
)
from infonav_gym.experiments.paths import Interrupted, check_output_dir
from infonav_gym.registry import PARALLEL, api_of, env_entry, make_env, resolve_env_id

DATA_HINT = "pip install 'infonav-gym[data]' (minari with its create and hdf5 extras, jax)"
DATASET_ID = re.compile(r"^[\w.-]+(/[\w.-]+)*-v\d+$")  # Minari's (namespace/)(env_name/)name-vN
DATA_DIR, METADATA_FILE = "data", "metadata.json"  # Minari keeps a dataset in DIR/ID/data, described by this file


def import_minari():
    """Minari, or ``ValueError`` saying how to install the data extra."""
    try:
        import jax  # noqa: F401  (Minari's DataCollector needs it, and says so only when it records)
        import minari
    except ImportError as error:
        raise ValueError(f"Minari datasets need the data extra: {DATA_HINT} ({error})") from None
    return minari


def default_dataset_id(env_id: str, agent_name: str) -> str:
    """``infonav/ENV/AGENT-v0``: the env id's last part lowercased, the agent's kind (``ppo``, not its path)."""
    return f"infonav/{env_id.rsplit('/', 1)[-1].lower()}/{agent_name.partition(':')[0]}-v0"


def recording_env(env_id: str, env_kwargs: dict) -> gym.Env:
    """The Gymnasium env the recording steps: ``env_id`` itself, or a team env's ``JointTeamEnv``."""
    if api_of(env_id) == PARALLEL:
        return gym.make(joint_spec(resolve_env_id(env_id), **env_kwargs))
    return make_env(env_id, **env_kwargs)


class TeamAgents:
    """One agent per robot of a ``JointTeamEnv``, acting as one: row ``k`` of the observation is robot ``k``'s; robot
    ``k``'s agent is reset with ``robot_seed(seed, k)``, as ``infonav evaluate`` resets them."""

    def __init__(self, agents: dict):
        self.agents = agents

    def reset(self, seed: int | None = None) -> None:
        for k, agent in enumerate(self.agents.values()):
            agent.reset(seed=robot_seed(seed, k))

    def act(self, observation, info: dict) -> np.ndarray:
        return np.array([agent.act(row, info[robot]) for row, (robot, agent) in zip(observation, self.agents.items())])


def recording_agent(agent_name: str, env: gym.Env):
    """The agent ``agent_name`` acting in ``env`` (a ``JointTeamEnv``: its robots' agents as ``TeamAgents``)."""
    team = getattr(env.unwrapped, "team", None)
    if team is not None:
        return TeamAgents(make_team_agents(agent_name, team))
    return make_agent(agent_name, env.action_space.n, traits_of(env).noop_action, env=env)


def record_dataset(
    env_id: str,
    agent_name: str,
    episodes: int,
    output: Path | str,
    dataset_id: str | None = None,
    seed: int = 0,
    env_kwargs: dict | None = None,
    overwrite: bool = False,
    progress: bool = True,
) -> dict:
    """Record ``agent_name`` for ``episodes`` episodes (seeds ``seed ..``) on ``env_id`` into the Minari dataset
    ``output/dataset_id`` (default ``default_dataset_id``). ``ValueError`` before any episode for bad input or an
    existing dataset without ``overwrite``; on Ctrl-C the finished episodes and the one cut short (truncated, as Minari
    cuts an episode reset before its end) are written, then ``Interrupted`` says so. Returns what was written."""
    minari = import_minari()
    seeds = seeds_of(seed, episodes)
    check_agent_name(agent_name)
    dataset_id = dataset_id or default_dataset_id(env_id, agent_name)
    if not DATASET_ID.match(dataset_id):
        raise ValueError(
            f"--dataset-id {dataset_id!r} is not a Minari dataset id: expected NAMESPACE/NAME-vVERSION, "
            "e.g. infonav/cooperative_exploration_v0/planner-v0"
        )
    output = check_output_dir(output, "--output")
    path = output / dataset_id
    if path.exists() and not overwrite:
        raise ValueError(f"dataset {path} exists: choose another --dataset-id or --output, or add --overwrite")
    env_kwargs = dict(env_kwargs or {})
    with _datasets_path(output):  # where the collector keeps its episodes until they are written
        collector = minari.DataCollector(recording_env(env_id, env_kwargs), record_infos=True)
    result = {"env_id": env_id, "env_kwargs": env_kwargs, "agent": agent_name, "dataset_id": dataset_id}
    try:
        agent = recording_agent(agent_name, collector)
    except ValueError:
        collector.close()
        raise
    finished = []
    bar = tqdm(total=episodes, desc=f"recording {agent_name} on {env_id}", unit="episode", disable=not progress)
    try:
        for episode_seed in seeds:
            for _ in episode_infos(collector, agent, episode_seed):  # the collector records each step
                pass
            finished.append(episode_seed)
            bar.update()
    except INTERRUPTIONS as error:
        if not pressed_ctrl_c(error):
            raise
        result["interrupted"] = True
    finally:
        bar.close()
    if path.exists():
        shutil.rmtree(path)
    description = f"infonav dataset: {agent_name} on {env_id} with config {env_kwargs}, seeds from {seed}"
    with _datasets_path(output), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"`\w+` is set to None", category=UserWarning)  # author, email, ...
        dataset = collector.create_dataset(dataset_id=dataset_id, algorithm_name=agent_name, description=description)
    collector.close()
    result |= {"seeds": finished, "episodes": dataset.total_episodes, "steps": dataset.total_steps}
    result["path"] = str(path)
    if result.get("interrupted"):
        raise Interrupted(
            f"interrupted after {len(finished)} of {episodes} episodes; wrote {path} with them and the episode cut "
            "short (truncated)",
            result,
        )
    return result


@contextlib.contextmanager
def _datasets_path(directory: Path):
    """Minari's datasets directory (``MINARI_DATASETS_PATH``) set to ``directory`` within the block."""
    before = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(directory)
    try:
        yield
    finally:
        if before is None:
            del os.environ["MINARI_DATASETS_PATH"]
        else:
            os.environ["MINARI_DATASETS_PATH"] = before


def load_recorded(path: Path | str):
    """The Minari dataset at ``path``: its directory (``--output``/``--dataset-id`` of ``infonav dataset``) or the
    ``data`` directory in it; ``ValueError`` naming a path that holds none or a dataset that does not load."""
    minari = import_minari()
    path = Path(path)
    data = path if (path / METADATA_FILE).is_file() else path / DATA_DIR
    if not (data / METADATA_FILE).is_file():
        raise ValueError(
            f"{path} is not a Minari dataset directory (no {DATA_DIR}/{METADATA_FILE}): give the DIR/ID that "
            "infonav dataset --output DIR --dataset-id ID wrote"
        )
    try:
        dataset = minari.MinariDataset(data)
    except Exception as error:  # h5py, JSON and Minari's own errors all mean "not a dataset that loads"
        raise ValueError(f"cannot load the Minari dataset {path}: {error}") from None
    if dataset.spec.env_spec is None:
        raise ValueError(f"the Minari dataset {path} keeps no env spec: it cannot say which env to clone for")
    return dataset


def clone_dataset(
    path: Path | str,
    output: Path | str,
    seed: int = 0,
    progress: bool = True,
    dagger_rounds: int = 0,
    dagger_episodes: int = 10,
    workers: int = 1,
    validation_episodes: int = 10,
) -> Path:
    """Behaviour cloning of the agent recorded in the dataset at ``path`` (``load_recorded``) into a ``MaskablePPO``
    policy for the env and config the dataset recreates, saved in ``output`` as ``infonav train`` saves models (PPO
    for 0 steps after cloning: ``infonav evaluate --agents ppo:OUTPUT`` plays it). ``dagger_rounds`` > 0: then that
    many rounds of DAgger with the env's planner (``infonav_gym.experiments.dagger``; ``ValueError`` for an env without
    a planning model). Returns the model's path."""
    from agents.imitation import Demonstrations
    from agents.ppo import load_hyperparameters, train

    dataset = load_recorded(path)
    env_id, env_kwargs = recorded_env(dataset.spec.env_spec)
    if dagger_rounds and not has_planning_model(env_entry(env_id).load()):
        raise ValueError(f"--dagger labels with the env's planner, and {env_id} has no planning model")
    gamma = load_hyperparameters(env_id).get("gamma", 0.99)
    demonstrations = Demonstrations.of_dataset(dataset, api_of(env_id) == PARALLEL, gamma)
    if dagger_rounds:
        from infonav_gym.experiments.dagger import dagger

        return dagger(
            env_id,
            env_kwargs,
            demonstrations,
            dagger_rounds,
            dagger_episodes,
            output,
            seed,
            gamma,
            workers,
            validation_episodes,
            progress,
        )
    return train(
        env_id,
        0,
        seed=seed,
        output_dir=output,
        env_kwargs=env_kwargs,
        init_from_planner=demonstrations,
        progress=progress,
    )
