"""The paper's Section III-B claims, on the corridor scenario (Figs. 1-2)."""

import gymnasium as gym
import numpy as np
import pytest

import infonav_gym  # noqa: F401

LANDMARK_3 = 2
ASSOCIATE_EACH_TWICE = [0, 1, 2, 3, 0, 1, 2, 3]


def landmark_3_leads(info, margin=1.1) -> bool:
    gains = info["action_information_gain"][:4]
    assert np.all(info["action_mask"][:4] == 1), "all four candidates are visible in this part of the corridor"
    others = np.delete(gains, LANDMARK_3)
    return bool(np.all(gains[LANDMARK_3] > margin * others))


@pytest.mark.parametrize("seed", range(5))
def test_landmark_3_brings_clearly_more_information_at_consecutive_steps(seed):
    """Fig. 2 (a)-(b): #3's information contribution exceeds each other landmark's, step after step."""
    env = gym.make("infonav/LandmarkSelection-v0", scenario="corridor")
    _, info = env.reset(seed=seed)
    for _ in range(4):
        assert landmark_3_leads(info)
        _, _, _, _, info = env.step(LANDMARK_3)


@pytest.mark.parametrize("seed", range(5))
def test_landmark_3_still_leads_after_every_landmark_was_associated_twice(seed):
    """Fig. 2 (c)-(d): after each landmark has been observed twice, #3 is still the one to pick."""
    env = gym.make("infonav/LandmarkSelection-v0", scenario="corridor")
    _, info = env.reset(seed=seed)
    for landmark in ASSOCIATE_EACH_TWICE:
        assert info["action_mask"][landmark] == 1
        _, reward, _, _, info = env.step(landmark)
        assert reward > 0
    for _ in range(3):
        assert landmark_3_leads(info)
        _, _, _, _, info = env.step(LANDMARK_3)


def test_greedy_selection_picks_landmark_3_in_the_corridor():
    from agents import GreedyEntropyAgent

    env = gym.make("infonav/LandmarkSelection-v0", scenario="corridor")
    observation, info = env.reset(seed=0)
    agent = GreedyEntropyAgent()
    choices = []
    for _ in range(10):
        action = agent.act(observation, info)
        choices.append(action)
        observation, _, _, _, info = env.step(action)
    assert choices == [LANDMARK_3] * 10
