"""The team envs as BenchMARL tasks (``InfonavTask``), through the suite's TorchRL env (``InfonavTorchEnv``), so that
BenchMARL's algorithms (MAPPO, IPPO, QMIX, ...) train on them::

    from benchmarl.algorithms import MappoConfig
    from benchmarl.experiment import Experiment, ExperimentConfig
    from benchmarl.models.mlp import MlpConfig

    task = InfonavTask.COOPERATIVE_EXPLORATION.get_task()  # the env's defaults; get_task({"observe_gains": True})
    Experiment(task, MappoConfig.get_from_yaml(), MlpConfig.get_from_yaml(), ExperimentConfig.get_from_yaml(),
               seed=0, critic_model_config=MlpConfig.get_from_yaml()).run()

A task's config is the env's keywords (its config keys). Actions are discrete, masked (``("agents",
"action_mask")``); the episode lasts the env's horizon.
"""

from __future__ import annotations

from benchmarl.environments.common import Task, TaskClass
from torchrl.data import Composite

from agents.torchrl_env import GROUP, InfonavTorchEnv

TASK_ENVS = {  # task name: the team env it plays
    "COOPERATIVE_LOCALIZATION": "cooperative_localization_v0",
    "COOPERATIVE_EXPLORATION": "cooperative_exploration_v0",
    "MRCLAM_COOPERATIVE_LOCALIZATION": "mrclam_cooperative_localization_v0",
}


class InfonavTaskClass(TaskClass):
    """A team env as BenchMARL's ``TaskClass``: ``self.config`` is the env's keywords."""

    def get_env_fun(self, num_envs: int, continuous_actions: bool, seed, device):
        env_id, config = TASK_ENVS[self.name], dict(self.config)
        return lambda: InfonavTorchEnv(env_id, num_envs, seed=seed, device=device, **config)

    def supports_continuous_actions(self) -> bool:
        return False

    def supports_discrete_actions(self) -> bool:
        return True

    def max_steps(self, env: InfonavTorchEnv) -> int:
        return env.vector.horizon

    def has_render(self, env: InfonavTorchEnv) -> bool:
        return False

    def group_map(self, env: InfonavTorchEnv) -> dict[str, list[str]]:
        return env.group_map

    def observation_spec(self, env: InfonavTorchEnv) -> Composite:
        return _group_entry(env, "observation")

    def action_mask_spec(self, env: InfonavTorchEnv) -> Composite:
        return _group_entry(env, "action_mask")

    def info_spec(self, env: InfonavTorchEnv) -> None:
        return None

    def state_spec(self, env: InfonavTorchEnv) -> None:
        return None

    def action_spec(self, env: InfonavTorchEnv) -> Composite:
        return env.full_action_spec_unbatched

    @staticmethod
    def env_name() -> str:
        return "infonav"


class InfonavTask(Task):
    """The suite's team envs as BenchMARL tasks (``TASK_ENVS``)."""

    COOPERATIVE_LOCALIZATION = None
    COOPERATIVE_EXPLORATION = None
    MRCLAM_COOPERATIVE_LOCALIZATION = None

    @staticmethod
    def associated_class():
        return InfonavTaskClass

    def get_from_yaml(self, path: str | None = None) -> InfonavTaskClass:
        """The task with the env's default config (the suite ships no task yaml; ``get_task(config)`` sets keys)."""
        return self.get_task(config={})


def _group_entry(env: InfonavTorchEnv, key: str) -> Composite:
    """``env``'s observation spec of one copy holding only the agent group's ``key``."""
    group = env.full_observation_spec_unbatched[GROUP]
    return Composite({GROUP: Composite({key: group[key].clone()}, shape=group.shape)})
