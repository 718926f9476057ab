"""RLlib's multi-agent env runner on a team env's native vector env: N copies in one batched step, one forward pass
per policy, where RLlib 2.60 steps multi-agent copies one by one in Python (needs Ray)."""

from __future__ import annotations

from collections import Counter

import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode
from ray.rllib.callbacks.callbacks import RLlibCallback
from ray.rllib.callbacks.utils import make_callback
from ray.rllib.env.env_context import EnvContext
from ray.rllib.env.multi_agent_env import MultiAgentEnv
from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner
from ray.rllib.env.vector.vector_multi_agent_env import VectorMultiAgentEnv
from ray.rllib.utils.metrics import (
    NUM_AGENT_STEPS_SAMPLED,
    NUM_AGENT_STEPS_SAMPLED_LIFETIME,
    NUM_ENV_STEPS_SAMPLED,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_EPISODES,
    NUM_EPISODES_LIFETIME,
    NUM_MODULE_STEPS_SAMPLED,
    NUM_MODULE_STEPS_SAMPLED_LIFETIME,
)
from ray.tune.registry import ENV_CREATOR, _global_registry

from agents.learning_curve import METRIC_KEY, EndedEpisodeMetrics, team_view
from agents.rllib_masking import ACTION_MASK, OBSERVATION, mask_rows, masked_space
from infonav_gym.envs.traits import main_metric_of

ALL = "__all__"  # RLlib's key of the whole team's termination and truncation
LIFETIME = {  # each count RLlib keeps per sample and over the runner's lifetime
    NUM_ENV_STEPS_SAMPLED: NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_EPISODES: NUM_EPISODES_LIFETIME,
    NUM_AGENT_STEPS_SAMPLED: NUM_AGENT_STEPS_SAMPLED_LIFETIME,
    NUM_MODULE_STEPS_SAMPLED: NUM_MODULE_STEPS_SAMPLED_LIFETIME,
}


class TeamCopy(MultiAgentEnv):
    """One copy of a ``BatchedTeamEnv`` as RLlib's runner reads it: its robots and their spaces (it steps there)."""

    def __init__(self, agents: list[str], observation_space: spaces.Space, action_space: spaces.Space):
        super().__init__()
        self.possible_agents, self.agents = list(agents), list(agents)
        self.observation_spaces = dict.fromkeys(agents, observation_space)
        self.action_spaces = dict.fromkeys(agents, action_space)


class BatchedTeamEnv(VectorMultiAgentEnv):
    """A team vector env (N copies of R robots, ``NEXT_STEP`` autoreset, else ``ValueError``) as RLlib's
    ``VectorMultiAgentEnv``. Copy ``i``'s observations are ``{robot: {"observation": ..., "action_mask": float32}}``
    (all ones where none is valid); rewards and terminations ``{robot: ...}`` with ``"__all__"``; infos ``{}`` but at
    an episode's last step ``{METRIC_KEY: main metric}``. The step after an end resets the copy (its actions ignored,
    rewards 0). ``reset(seed=s)`` seeds copy ``i`` with ``s + i``."""

    closed = True  # until built: a construction that failed has nothing to close

    def __init__(self, team):
        super().__init__()
        if team.autoreset_mode != AutoresetMode.NEXT_STEP:
            raise ValueError(f"BatchedTeamEnv needs a vector env in NEXT_STEP autoreset, got {team.autoreset_mode}")
        self.team, self.num_envs, self.agents = team, team.num_envs, list(team.agents)
        self.metadata = {**team.metadata, "autoreset_mode": AutoresetMode.NEXT_STEP.value}
        self.render_mode = team.render_mode
        observation_space = masked_space(team.single_observation_space, int(team.single_action_space.n))
        self.single_observation_spaces = dict.fromkeys(self.agents, observation_space)
        self.single_action_spaces = dict.fromkeys(self.agents, team.single_action_space)
        self.single_observation_space = spaces.Dict(self.single_observation_spaces)
        self.single_action_space = spaces.Dict(self.single_action_spaces)
        self.envs = [TeamCopy(self.agents, observation_space, team.single_action_space) for _ in range(self.num_envs)]
        self._actions = np.zeros((self.num_envs, len(self.agents)), dtype=np.int64)
        self._restarting = np.zeros(self.num_envs, dtype=bool)
        view = team_view(self.agents, team.team_info_keys)
        self.episode_metrics = EndedEpisodeMetrics(main_metric_of(team), self.num_envs, view, same_step=False)
        self.closed = False

    def reset(self, *, seed=None, options=None):
        observations, _ = self.team.reset(seed=seed, options=options)
        self._restarting[:] = False
        self.episode_metrics.reset()
        return self._observations(observations), [{} for _ in range(self.num_envs)]

    def step(self, actions: list[dict]):
        """Step copy ``i`` with ``actions[i]``: ``{robot: action}`` of every robot but in a restarting copy."""
        if len(actions) != self.num_envs:
            raise ValueError(f"expected one {{robot: action}} dict per copy ({self.num_envs}), got {len(actions)}")
        for copy, copy_actions in enumerate(actions):
            if self._restarting[copy]:
                continue  # NEXT_STEP: the vector env resets this copy and ignores its actions
            try:
                self._actions[copy] = [copy_actions[agent] for agent in self.agents]
            except KeyError as missing:
                raise ValueError(f"copy {copy} has no action for {missing.args[0]}: got {copy_actions!r}") from None
        observations, rewards, terminated, truncated, info = self.team.step(self._actions)
        self._restarting = terminated[:, 0] | truncated[:, 0]
        metrics = self.episode_metrics.step(info, self._restarting)
        infos = [{} for _ in range(self.num_envs)]
        for copy in np.flatnonzero(self._restarting).tolist():
            infos[copy] = {agent: {METRIC_KEY: metrics[copy]} for agent in self.agents}
        return (
            self._observations(observations),
            [dict(zip(self.agents, copy_rewards)) for copy_rewards in rewards.tolist()],
            _team_flags(self.agents, terminated[:, 0]),
            _team_flags(self.agents, truncated[:, 0]),
            infos,
        )

    def _observations(self, observations: np.ndarray) -> list[dict]:
        """Each copy's ``{robot: {"observation", "action_mask"}}``, copied (RLlib's episodes keep them)."""
        observations = np.array(observations, dtype=np.float32)
        masks = mask_rows(self.team.action_masks())
        return [
            {
                agent: {OBSERVATION: observations[copy, robot], ACTION_MASK: masks[copy, robot]}
                for robot, agent in enumerate(self.agents)
            }
            for copy in range(self.num_envs)
        ]

    def render(self):
        return self.team.render()

    def close_extras(self, **kwargs) -> None:
        self.team.close()


class CurveMetricCallback(RLlibCallback):
    """Logs each ended episode's main metric (``METRIC_KEY`` in its last infos) as RLlib logs the episode return:
    a mean over the last ``metrics_num_episodes_for_smoothing`` episodes, in the results' ``env_runners``."""

    def on_episode_end(self, *, episode, env_runner=None, metrics_logger=None, **kwargs) -> None:
        infos = [info for info in episode.get_infos(-1).values() if METRIC_KEY in info]
        if infos and metrics_logger is not None:
            window = env_runner.config.metrics_num_episodes_for_smoothing
            metrics_logger.log_value(METRIC_KEY, float(infos[0][METRIC_KEY]), reduce="mean", window=window)


def _team_flags(agents: list[str], ended: np.ndarray) -> list[dict]:
    """Per copy: every robot's flag and ``"__all__"``, the copy's (the robots of a copy end together)."""
    return [{**dict.fromkeys(agents, flag), ALL: flag} for flag in ended.tolist()]


class BatchedTeamEnvRunner(MultiAgentEnvRunner):
    """RLlib's ``MultiAgentEnvRunner`` on one ``BatchedTeamEnv`` for all copies (its creator gets ``num_envs``).

    All else is RLlib's, but the sampled step and episode counts, which RLlib logs copy by copy every step (a quarter
    of a copy's step), are summed and logged once per ``sample()``: the same sums.
    """

    def __init__(self, config, **kwargs):
        self._sampled = Counter()  # (metric, key or None) -> count since the last log
        super().__init__(config=config, **kwargs)

    def _increase_sampled_metrics(self, num_steps, next_obs, episode):
        self._sampled[NUM_ENV_STEPS_SAMPLED, None] += num_steps
        self._sampled[NUM_EPISODES, None] += int(episode.is_done)
        for agent in next_obs:
            self._sampled[NUM_AGENT_STEPS_SAMPLED, str(agent)] += 1
            self._sampled[NUM_MODULE_STEPS_SAMPLED, episode.module_for(agent)] += 1
        return num_steps

    def _sample(self, **kwargs):
        try:
            return super()._sample(**kwargs)
        finally:
            self._log_sampled()

    def _log_sampled(self) -> None:
        """Log the counts summed since the last call as RLlib's ``_increase_sampled_metrics`` logs them."""
        for (metric, key), count in self._sampled.items():
            if count:
                name = metric if key is None else (metric, key)
                self.metrics.log_value(name, count, reduce="sum")
                lifetime = LIFETIME[metric] if key is None else (LIFETIME[metric], key)
                self.metrics.log_value(
                    lifetime, count, reduce="lifetime_sum", with_throughput=metric == NUM_ENV_STEPS_SAMPLED
                )
        self._sampled.clear()

    def make_env(self):
        if self.env is not None:
            self.env.close()
        env_config = {**self.config.env_config, "num_envs": self.config.num_envs_per_env_runner}
        context = EnvContext(
            env_config,
            worker_index=self.worker_index,
            num_workers=self.config.num_env_runners,
            remote=self.config.remote_worker_envs,
        )
        self.env = _global_registry.get(ENV_CREATOR, self.config.env)(context)
        self.num_envs = self.env.num_envs
        self._needs_initial_reset = True
        make_callback(
            "on_environment_created",
            callbacks_objects=self._callbacks,
            callbacks_functions=self.config.callbacks_on_environment_created,
            kwargs={"env_runner": self, "metrics_logger": self.metrics, "env": self.env, "env_context": context},
        )
