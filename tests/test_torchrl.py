"""TorchRL's own wrappers take every env as it comes (issue 45): ``GymWrapper`` of each single-agent env and of its
native vector env (default autoreset: ``SAME_STEP``, the mode TorchRL reads), ``PettingZooWrapper`` of each team env;
``check_env_specs`` passes on each, and the reward terms reach TorchRL's data as the flat info keys they are."""

from __future__ import annotations

import pytest

from infonav_gym.envs.traits import traits_of
from infonav_gym.envs.vector_infos import reward_term_key
from infonav_gym.registry import GYMNASIUM, PARALLEL, available_envs, make_env, make_vector_env

pytest.importorskip("torchrl", reason="torchrl is not installed (the test extra)")
from torchrl.envs import GymWrapper, PettingZooWrapper  # noqa: E402
from torchrl.envs.utils import check_env_specs  # noqa: E402

SINGLE_IDS = [entry.id for entry in available_envs(GYMNASIUM)]  # a warning names each env without its dataset
TEAM_IDS = [entry.id for entry in available_envs(PARALLEL)]
HORIZON = 2  # TorchRL's 3-step check crosses an episode end (and the vector env's autoreset)


@pytest.mark.parametrize("env_id", SINGLE_IDS)
def test_gym_wrapper_takes_the_single_env(env_id):
    env = GymWrapper(make_env(env_id, horizon=HORIZON))
    check_env_specs(env, seed=0)
    assert env.rollout(3)["next", "done"].squeeze(-1).tolist() == [False, True]


@pytest.mark.parametrize("env_id", SINGLE_IDS)
def test_gym_wrapper_takes_the_native_vector_env_through_an_autoreset_and_reads_its_reward_terms(env_id):
    env = GymWrapper(make_vector_env(env_id, 2, horizon=HORIZON))
    check_env_specs(env, seed=0)
    step = env.rollout(3, break_when_any_done=False)["next"]
    assert step["done"].squeeze(-1).tolist() == [[False, True, False]] * 2  # SAME_STEP: its final_info read
    terms = [step[reward_term_key(term)] for term in traits_of(env.unwrapped).reward_terms]
    assert len(terms) > 0
    assert (sum(terms).float() - step["reward"].squeeze(-1)).abs().max() < 1e-4  # the reward is its terms' sum


@pytest.mark.parametrize("env_id", TEAM_IDS)
def test_pettingzoo_wrapper_takes_the_team_env_with_its_action_masks(env_id):
    env = PettingZooWrapper(make_env(env_id, max_cycles=HORIZON), use_mask=True)
    check_env_specs(env, seed=0)
    (group,) = env.group_map
    step = env.rollout(3)
    assert step[group, "action_mask"].any(-1).all()
    for term in make_env(env_id).traits.reward_terms:
        assert (group, "info", reward_term_key(term)) in step["next"].keys(True, True)
