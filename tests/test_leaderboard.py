"""The env's main metric (``traits.main_metric``), which ``infonav leaderboard`` ranks agents by."""

import pytest

from infonav_gym.envs.metrics import SUCCESS_RATE
from infonav_gym.envs.traits import EnvTraits, episode_metrics_of, main_metric_of
from infonav_gym.registry import make_env, registered_envs


@pytest.mark.parametrize("entry", registered_envs(), ids=lambda entry: entry.id)
def test_every_registered_env_declares_a_main_metric_among_its_episode_metrics(entry):
    env = make_env(entry.id)
    try:
        assert main_metric_of(env) in episode_metrics_of(env)
    finally:
        env.close()


def test_a_main_metric_that_is_not_an_episode_metric_is_refused_by_name():
    class Undeclared:
        episode_metrics = (SUCCESS_RATE,)
        traits = EnvTraits(main_metric="speed")
        unwrapped = property(lambda self: self)

    with pytest.raises(ValueError, match=r"^Undeclared.traits.main_metric is 'speed', .*name one of success_rate$"):
        main_metric_of(Undeclared())
