"""Actions are one integer of the ``Discrete`` space, however they are wrapped; anything else is a ``ValueError``."""

import pickle
import re

import gymnasium as gym
import numpy as np
import pytest
from conftest import assert_identical

import infonav_gym  # noqa: F401  (registers the envs)
from infonav_gym.envs.base import discrete_action_index
from infonav_gym.multi import cooperative_localization_v0

SPACE = gym.spaces.Discrete(4)
SAME_AS_ZERO = [0, [0], (0,), np.array([0]), np.array([[0]]), np.array(0), np.int64(0), np.uint8(0), [np.int32(0)]]
NOT_ACTIONS = [0.0, 1.5, np.float64(0), np.array([0.0]), [0.0], True, np.bool_(False), np.array([True]), [True]]
NOT_ACTIONS += [-1, 4, np.array([4]), [0, 1], np.array([0, 1]), [[0], [1]], [], np.array([]), [[0], [1, 2]]]
NOT_ACTIONS += ["0", None, {"action": 0}]


@pytest.mark.parametrize("action", SAME_AS_ZERO, ids=repr)
def test_integer_forms_of_one_action_are_the_same_index(action):
    index = discrete_action_index(action, SPACE)
    assert index == 0 and type(index) is int


@pytest.mark.parametrize("action", NOT_ACTIONS, ids=repr)
def test_anything_else_raises_naming_the_action_and_the_space(action):
    with pytest.raises(ValueError, match=r"action .* is not in the action space Discrete\(4\)") as error:
        discrete_action_index(action, SPACE)
    assert repr(action) in str(error.value)


def test_the_team_env_names_the_agent():
    with pytest.raises(ValueError, match=r"action \[0, 1\] of robot_2 is not in the action space Discrete\(4\)"):
        discrete_action_index([0, 1], SPACE, agent="robot_2")


@pytest.mark.parametrize("env_id", ["infonav/LandmarkSelection-v0", "infonav/SensorSelection-v0"])
def test_an_env_steps_alike_for_every_form_of_the_same_action(env_id):
    env = gym.make(env_id).unwrapped
    _, info = env.reset(seed=1)
    action = int(np.flatnonzero(info["action_mask"])[-1])
    reference = pickle.loads(pickle.dumps(env)).step(action)
    for form in ([action], np.array([action]), np.array([[action]]), np.int64(action), np.array(action)):
        assert_identical(pickle.loads(pickle.dumps(env)).step(form), reference, f"action {form!r}")


def test_the_team_env_treats_action_forms_alike_and_rejects_the_rest_naming_the_agent():
    env = cooperative_localization_v0.parallel_env()
    env.reset(seed=0)
    reference = pickle.loads(pickle.dumps(env)).step(dict.fromkeys(env.agents, 0))
    for form in ([0], np.array([[0]]), np.int64(0)):
        assert_identical(
            pickle.loads(pickle.dumps(env)).step({**dict.fromkeys(env.agents, 0), "robot_1": form}), reference
        )
    for bad in (0.0, True, [0, 1], 5):
        with pytest.raises(ValueError, match=re.escape(f"action {bad!r} of robot_1 is not in the action space")):
            env.step({**dict.fromkeys(env.agents, 0), "robot_1": bad})
