"""The AEC team envs refuse an invalid action at the ``step`` that gives it, naming its agent (not a turn later)."""

import numpy as np
import pytest

from infonav_gym.multi import cooperative_exploration_v0, cooperative_localization_v0

TEAM_ENVS = [cooperative_localization_v0, cooperative_exploration_v0]


@pytest.mark.parametrize("module", TEAM_ENVS)
@pytest.mark.parametrize("bad_action", [99, -1, 2.5, "a", None, np.array([0, 1])])
def test_an_action_outside_the_space_is_refused_at_its_own_step(module, bad_action):
    env = module.env()
    env.reset(seed=0)
    top = env.action_space("robot_0").n - 1
    with pytest.raises(ValueError, match=rf"action .* of robot_0 is not in the action space .*\[0, {top}\]"):
        env.step(bad_action)
    assert env.agent_selection == "robot_0", "the turn stays with the agent that gave the bad action"
    env.step(0)
    assert env.agent_selection == "robot_1"


@pytest.mark.parametrize("module", TEAM_ENVS)
def test_a_masked_action_is_refused_at_its_own_step_with_invalid_action_raise(module):
    env = module.env(invalid_action="raise")
    env.reset(seed=0)
    env.step(0)  # robot_0: the no-op, always valid
    mask = env.infos["robot_1"]["action_mask"]
    masked = int(np.flatnonzero(mask == 0)[0])
    with pytest.raises(ValueError, match=rf"action {masked} of robot_1 is not valid now"):
        env.step(masked)
    assert env.agent_selection == "robot_1"
