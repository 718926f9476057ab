"""Episode metrics an env declares for the evaluation harness, and the metric functions they share.

An env class lists its metrics in ``episode_metrics``. Each metric computes one number from
an episode's infos: the per-step info dicts of a single-agent env (the reset info excluded),
or, for a PettingZoo parallel env, the per-step dicts ``{agent: info}``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from infonav_gym.envs.vector_infos import reward_term_key, reward_terms_of


@dataclass(frozen=True)
class EpisodeMetric:
    """One number per episode, summarized over episodes by the harness.

    Attributes:
        name: the key in the results (``"cumulative_mi"``).
        title: the axis and column title, its unit in brackets (``"cumulative MI [nats]"``, ``"success rate [-]"``):
            every table and plot that names the metric shows it.
        compute: the value from the episode's infos (see the module docstring).
        proportion: the values are 0 or 1 (a rate): summarized by a Wilson score interval, not Student t.
    """

    name: str
    title: str
    compute: Callable[[Sequence], float]
    proportion: bool = False


def summed_reward_term(term: str) -> Callable[[Sequence[dict]], float]:
    """The episode's sum (``math.fsum``) of the reward term ``term`` (``reward_terms_of``; 0 in steps without it)."""
    return lambda infos: math.fsum(reward_terms_of(step).get(term, 0.0) for step in infos)


def summed_reward(infos: Sequence[dict]) -> float:
    """The episode's return: every reward term of every step (``math.fsum`` per step, then over steps)."""
    return math.fsum(math.fsum(reward_terms_of(step).values()) for step in infos)


def summed_info(key: str) -> Callable[[Sequence[dict]], float]:
    """The episode's sum of ``info[key]`` (a count or an amount each step has)."""
    return lambda infos: sum(step[key] for step in infos)


def final_value(key: str) -> Callable[[Sequence[dict]], float]:
    """``info[key]`` of the episode's last step."""
    return lambda infos: infos[-1][key]


def final_flag(key: str) -> Callable[[Sequence[dict]], float]:
    """1.0 if ``info[key]`` of the last step is true, else 0.0 (a ``proportion`` metric)."""
    return lambda infos: float(bool(infos[-1][key]))


def root_mean_square(key: str) -> Callable[[Sequence[dict]], float]:
    """The root mean square over the episode's steps of ``info[key]``."""
    return lambda infos: math.sqrt(float(np.mean([step[key] ** 2 for step in infos])))


def mean_where(key: str, condition: Callable[[dict], bool]) -> Callable[[Sequence[dict]], float]:
    """The mean of ``info[key]`` over the steps whose info meets ``condition`` (0.0 if none does)."""

    def compute(infos: Sequence[dict]) -> float:
        values = [step[key] for step in infos if condition(step)]
        return float(np.mean(values)) if values else 0.0

    return compute


def count_where(condition: Callable[[dict], bool]) -> Callable[[Sequence[dict]], int]:
    """How many steps' infos meet ``condition``."""
    return lambda infos: sum(1 for step in infos if condition(step))


def team_summed_reward_term(term: str) -> Callable[[Sequence[dict]], float]:
    """A parallel env's sum over steps of the first agent's reward ``term`` (a term every agent shares).

    Added step by step in order, as the committed team results were.
    """

    key = reward_term_key(term)

    def compute(steps: Sequence[dict]) -> float:
        total = 0.0
        for infos in steps:
            total += next(iter(infos.values()))[key]
        return total

    return compute


def team_mean_final_value(key: str) -> Callable[[Sequence[dict]], float]:
    """The mean over agents of ``info[key]`` at the last step of a parallel env."""
    return lambda steps: float(np.mean([info[key] for info in steps[-1].values()]))


def team_mean_root_mean_square(key: str) -> Callable[[Sequence[dict]], float]:
    """The mean over agents of each agent's root mean square over the steps of ``info[key]`` (parallel env)."""

    def compute(steps: Sequence[dict]) -> float:
        squares = np.zeros(len(steps[0]))
        for infos in steps:
            squares += [info[key] ** 2 for info in infos.values()]
        return float(np.mean(np.sqrt(squares / len(steps))))

    return compute


def team_total_reward_term(term: str) -> Callable[[Sequence[dict]], float]:
    """A parallel env's sum over steps and agents of its reward ``term`` (a term of each robot's own)."""
    key = reward_term_key(term)
    return lambda steps: math.fsum(info[key] for infos in steps for info in infos.values())


def team_final_flag(key: str) -> Callable[[Sequence[dict]], float]:
    """1.0 if the first agent's ``info[key]`` (a flag every agent shares) is true at a parallel env's last step."""
    return lambda steps: float(bool(next(iter(steps[-1].values()))[key]))


CUMULATIVE_MI_TITLE = "cumulative MI [nats]"
POSE_ENTROPY_TITLE = "final pose entropy [nats]"
RMSE_TITLE = "position RMSE [m]"
LOCALIZATION_METRICS = (
    EpisodeMetric("cumulative_mi", CUMULATIVE_MI_TITLE, summed_reward_term("mutual_information")),
    EpisodeMetric("final_pose_entropy", POSE_ENTROPY_TITLE, final_value("pose_entropy")),
    EpisodeMetric("pose_rmse_m", RMSE_TITLE, root_mean_square("position_error_m")),
)
TEAM_LOCALIZATION_METRICS = (  # the team's (joint-state) MI; entropy and RMSE are means over the robots
    EpisodeMetric("cumulative_mi", "team " + CUMULATIVE_MI_TITLE, team_summed_reward_term("team_mutual_information")),
    EpisodeMetric("final_pose_entropy", POSE_ENTROPY_TITLE, team_mean_final_value("pose_entropy")),
    EpisodeMetric("pose_rmse_m", RMSE_TITLE, team_mean_root_mean_square("position_error_m")),
)
EXPLORATION_METRICS = (  # cooperative_exploration_v0: the team's success, coverage and information
    EpisodeMetric("success_rate", "success rate [-]", team_final_flag("success"), proportion=True),
    EpisodeMetric("failure_rate", "robot lost rate [-]", team_final_flag("failed"), proportion=True),
    EpisodeMetric("final_coverage", "final coverage [-]", team_mean_final_value("coverage")),
    EpisodeMetric("map_information", "team map information [nats]", team_summed_reward_term("team_map_information")),
    EpisodeMetric("pose_information", "team pose MI [nats]", team_total_reward_term("own_pose_information")),
    EpisodeMetric("episode_steps", "episode length [steps]", len),
)
SUCCESS_RATE = EpisodeMetric("success_rate", "success rate [-]", final_flag("success"), proportion=True)
