"""Tests of the baseline agents, and the acceptance claim: greedy entropy beats random."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.wrappers import RecordEpisodeStatistics, TimeLimit
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chisquare

import agents
import infonav_gym  # noqa: F401  (registers the envs)
from agents import GreedyEntropyAgent, NearestAgent, RandomAgent
from infonav_gym import make_env
from infonav_gym.decisions import DECISION_ATOL, DECISION_RTOL
from infonav_gym.experiments.episodes import make_agent

LANDMARK_ID = "infonav/LandmarkSelection-v0"


def greedy_info(gains, mask=None) -> dict:
    info = {"action_information_gain": np.asarray(gains, dtype=np.float64)}
    if mask is not None:
        info["action_mask"] = np.asarray(mask, dtype=np.int8)
    return info


# ----------------------------------------------------------------------------- GreedyEntropyAgent


def test_greedy_never_picks_a_masked_action_even_with_the_largest_gain():
    info = greedy_info([0.1, 0.9, 0.5, 0.3], mask=[1, 0, 1, 1])
    assert GreedyEntropyAgent().act(None, info) == 2


def test_greedy_picks_the_argmax_gain_among_valid_actions():
    assert GreedyEntropyAgent().act(None, greedy_info([0.1, 0.2, 0.7, 0.3], mask=[1, 1, 1, 1])) == 2
    assert GreedyEntropyAgent().act(None, greedy_info([0.4, 0.0, 0.0, 0.3], mask=[1, 0, 0, 1])) == 0


def test_greedy_breaks_ties_by_the_lowest_valid_index():
    assert GreedyEntropyAgent().act(None, greedy_info([0.2, 0.5, 0.5, 0.5], mask=[1, 1, 1, 1])) == 1
    assert GreedyEntropyAgent().act(None, greedy_info([0.2, 0.5, 0.5, 0.5], mask=[1, 0, 1, 1])) == 2
    assert GreedyEntropyAgent().act(None, greedy_info([0.5, 0.5])) == 0


@pytest.mark.parametrize("gains", [[0.0, 0.0, 0.0], [0.3, 0.9, 0.1]])
def test_greedy_returns_action_0_when_no_action_is_valid(gains):
    assert GreedyEntropyAgent().act(None, greedy_info(gains, mask=[0, 0, 0])) == 0


def test_greedy_without_gain_in_info_raises_a_clear_value_error():
    with pytest.raises(ValueError, match=r'GreedyEntropyAgent needs info\["action_information_gain"\]'):
        GreedyEntropyAgent().act(None, {"action_mask": np.ones(3, dtype=np.int8)})


def test_greedy_without_a_mask_takes_the_argmax_over_all_actions():
    assert GreedyEntropyAgent().act(None, greedy_info([0.1, 0.3, 0.2])) == 1


def test_greedy_returns_a_python_int_and_accepts_list_and_bool_masks():
    agent = GreedyEntropyAgent()
    action = agent.act(None, {"action_information_gain": [0.1, 0.9, 0.5], "action_mask": [True, False, True]})
    assert type(action) is int and action == 2
    agent.reset(seed=3)  # stateless: reset changes nothing
    assert agent.act(None, greedy_info([0.1, 0.9, 0.5], mask=[1, 0, 1])) == 2


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.tuples(st.floats(0.0, 10.0, allow_nan=False, allow_subnormal=False), st.booleans()), min_size=1, max_size=12
    )
)
def test_greedy_choice_is_the_lowest_index_near_maximizer_over_valid_actions(pairs):
    gains = [gain for gain, _ in pairs]
    mask = [int(valid) for _, valid in pairs]
    action = GreedyEntropyAgent().act(None, greedy_info(gains, mask))
    valid = [i for i, m in enumerate(mask) if m]
    if not valid:
        assert action == 0
    else:
        best = max(gains[i] for i in valid)
        band = DECISION_RTOL * best + DECISION_ATOL  # the gains are >= 0
        assert action == min(i for i in valid if gains[i] >= best - band)


# ----------------------------------------------------------------------------- RandomAgent

MASK = np.array([1, 0, 1, 1, 0, 1, 1, 0], dtype=np.int8)


def draw(agent, info, n) -> list[int]:
    return [agent.act(None, info) for _ in range(n)]


def test_random_agent_only_returns_valid_actions():
    actions = draw(RandomAgent(len(MASK), seed=0), {"action_mask": MASK}, 1000)
    assert all(type(a) is int for a in actions)
    assert set(actions) == set(np.flatnonzero(MASK).tolist())


def test_random_agent_is_uniform_over_valid_actions():
    actions = draw(RandomAgent(len(MASK), seed=1234), {"action_mask": MASK}, 1000)
    counts = np.bincount(actions, minlength=len(MASK))[MASK == 1]
    assert chisquare(counts).pvalue > 1e-3, counts


def test_random_agent_without_a_mask_is_uniform_over_all_actions():
    actions = draw(RandomAgent(5, seed=7), {}, 1000)
    assert chisquare(np.bincount(actions, minlength=5)).pvalue > 1e-3
    assert set(actions) == set(range(5))


def test_random_agent_with_no_valid_action_returns_an_action_in_range():
    actions = draw(RandomAgent(4, seed=0), {"action_mask": np.zeros(4, dtype=np.int8)}, 100)
    assert set(actions) <= set(range(4))


def test_random_agent_rejects_a_mask_of_the_wrong_shape():
    with pytest.raises(ValueError, match="action_mask"):
        RandomAgent(4, seed=0).act(None, {"action_mask": np.ones(3, dtype=np.int8)})


def test_random_agent_same_seed_gives_the_same_sequence():
    info = {"action_mask": MASK}
    assert draw(RandomAgent(8, seed=42), info, 200) == draw(RandomAgent(8, seed=42), info, 200)
    assert draw(RandomAgent(8, seed=42), info, 200) != draw(RandomAgent(8, seed=43), info, 200)


def test_random_agent_reset_with_a_seed_reseeds_it():
    info = {"action_mask": MASK}
    agent = RandomAgent(8, seed=1)
    draw(agent, info, 37)
    agent.reset(seed=99)
    assert draw(agent, info, 200) == draw(RandomAgent(8, seed=99), info, 200)


@pytest.mark.parametrize("n_actions", [0, -3])
def test_random_agent_needs_at_least_one_action(n_actions):
    with pytest.raises(ValueError, match="n_actions"):
        RandomAgent(n_actions)


# ----------------------------------------------------------------------------- protocol


@pytest.mark.parametrize("agent", [GreedyEntropyAgent(), RandomAgent(3, seed=0)], ids=["greedy", "random"])
def test_agents_satisfy_the_agent_protocol(agent):
    assert isinstance(agent, agents.Agent)


# ----------------------------------------------------------------------------- acceptance


def run_episode(env, agent, seed: int) -> tuple[float, dict, list[int], list[float]]:
    observation, info = env.reset(seed=seed)
    agent.reset(seed=seed)
    total, actions, rewards = 0.0, [], []
    terminated = truncated = False
    while not (terminated or truncated):
        action = agent.act(observation, info)
        observation, reward, terminated, truncated, info = env.step(action)
        total += reward
        actions.append(action)
        rewards.append(reward)
    return total, info, actions, rewards


def test_greedy_entropy_beats_random_on_every_seed_of_the_default_field_scenario():
    env = gym.make(LANDMARK_ID)
    n = env.action_space.n
    greedy_returns, random_returns, greedy_entropy, random_entropy = [], [], [], []
    for seed in range(20):
        g_return, g_info, _, _ = run_episode(env, GreedyEntropyAgent(), seed)
        r_return, r_info, _, _ = run_episode(env, RandomAgent(n, seed=seed), seed)
        greedy_returns.append(g_return)
        random_returns.append(r_return)
        greedy_entropy.append(g_info["pose_entropy"])
        random_entropy.append(r_info["pose_entropy"])
    losing = [s for s in range(20) if not greedy_returns[s] > random_returns[s]]
    assert not losing, f"greedy did not beat random on seeds {losing}: {greedy_returns} vs {random_returns}"
    assert np.mean(greedy_entropy) < np.mean(random_entropy), (greedy_entropy, random_entropy)


def test_greedy_gives_the_same_actions_and_rewards_through_wrappers():
    horizon = 60
    bare = gym.make(LANDMARK_ID, horizon=horizon).unwrapped
    wrapped = RecordEpisodeStatistics(TimeLimit(gym.make(LANDMARK_ID, horizon=horizon), max_episode_steps=horizon))
    bare_return, _, bare_actions, bare_rewards = run_episode(bare, GreedyEntropyAgent(), seed=17)
    wrapped_return, final_info, wrapped_actions, wrapped_rewards = run_episode(wrapped, GreedyEntropyAgent(), seed=17)
    assert len(bare_actions) == horizon
    assert wrapped_actions == bare_actions
    assert wrapped_rewards == bare_rewards
    assert len(set(bare_actions)) > 1, "greedy never changed its choice: the comparison would be weak"
    assert final_info["episode"]["l"] == horizon
    assert final_info["episode"]["r"] == pytest.approx(bare_return, rel=1e-12)


def test_nearest_agent_fuses_the_nearest_valid_reading_and_idles_without_one():
    agent = NearestAgent()
    info = {"action_range_m": np.array([0.0, 3.0, 1.5, 1.5, 0.5]), "action_mask": np.array([1, 1, 1, 1, 0])}
    assert agent.act(None, info) == 2  # 0.5 m is masked; 1.5 m twice: the lower index
    assert agent.act(None, {"action_range_m": np.zeros(3), "action_mask": np.array([1, 0, 0])}) == 0
    with pytest.raises(ValueError, match=r'NearestAgent needs info\["action_range_m"\]'):
        agent.act(None, {"action_mask": np.ones(2)})


def test_nearest_is_offered_only_where_the_infos_give_ranges():
    env = make_env("infonav/MRCLAMLocalization-v0", horizon=5)
    agent = make_agent("nearest", env.action_space.n, env=env)
    _, info = env.reset(seed=0)
    for _ in range(5):
        action = agent.act(None, info)
        measured = np.flatnonzero(info["action_mask"][1:]) + 1
        assert action == measured[np.argmin(info["action_range_m"][measured])] if measured.size else action == 0
        _, _, _, _, info = env.step(action)
    with pytest.raises(
        ValueError, match="agent 'nearest' is not available for infonav/LandmarkSelection-v0: .*use it on"
    ):
        make_agent("nearest", 9, env=make_env("infonav/LandmarkSelection-v0"))
