"""RLlib's view of a team vector env (``agents.rllib_team_env.BatchedTeamEnv``): each copy gets its numbers.

No Ray runtime is started: the adapter is stepped as RLlib's multi-agent runner steps it (a list of per-copy
``{robot: action}`` dicts, an empty one for a copy that restarts), beside the vector env it wraps.
"""

import numpy as np
import pytest

pytest.importorskip("ray", reason="the distributed extra (ray[rllib]) is not installed")

from gymnasium.vector import AutoresetMode  # noqa: E402

from agents.learning_curve import METRIC_KEY  # noqa: E402
from agents.rllib_masking import ACTION_MASK, OBSERVATION  # noqa: E402
from agents.rllib_team_env import ALL, BatchedTeamEnv  # noqa: E402
from agents.rllib_train import TeamEnvCreator  # noqa: E402
from infonav_gym.envs.traits import main_metric_of  # noqa: E402
from infonav_gym.registry import make_env, make_vector_env  # noqa: E402

# RLlib: slow; `pytest -m "not slow"` leaves it out while developing
pytestmark = pytest.mark.slow

COPIES, STEPS = 4, 40
TEAM_CONFIGS = [
    ("cooperative_localization_v0", {"max_cycles": 7}),
    ("cooperative_exploration_v0", {"max_cycles": 30, "coverage_target": 0.05}),  # copies end at different steps
]


def _pair(env_id: str, config: dict) -> tuple:
    """The adapter as RLlib's env creator makes it, and the same vector env beside it."""
    adapter = TeamEnvCreator(env_id)({"num_envs": COPIES, **config})
    reference = make_vector_env(env_id, COPIES, autoreset_mode=AutoresetMode.NEXT_STEP, **config)
    return adapter, reference


def _assert_copies_equal(adapter: BatchedTeamEnv, observations: list, reference_observations, masks) -> None:
    usable = np.where(masks.any(axis=2, keepdims=True), masks, True).astype(np.float32)
    for copy, copy_observations in enumerate(observations):
        assert list(copy_observations) == adapter.agents
        for robot, agent in enumerate(adapter.agents):
            observation = copy_observations[agent]
            assert adapter.single_observation_spaces[agent].contains(observation)
            np.testing.assert_array_equal(observation[OBSERVATION], reference_observations[copy, robot])
            np.testing.assert_array_equal(observation[ACTION_MASK], usable[copy, robot])


@pytest.mark.parametrize(("env_id", "config"), TEAM_CONFIGS)
def test_each_copy_gets_the_vector_envs_observations_masks_rewards_and_episode_ends(env_id, config):
    adapter, reference = _pair(env_id, config)
    observations, infos = adapter.reset(seed=5)
    reference_observations, _ = reference.reset(seed=5)
    assert infos == [{}] * COPIES
    _assert_copies_equal(adapter, observations, reference_observations, reference.action_masks())
    rng, restarting, end_steps = np.random.default_rng(0), np.zeros(COPIES, dtype=bool), []
    singles = [make_env(env_id, **config) for _ in range(COPIES)]  # copy i is the parallel env from seed 5 + i
    for copy, single in enumerate(singles):
        single.reset(seed=5 + copy)
    episodes = [[] for _ in singles]
    for step in range(STEPS):
        masks = reference.action_masks()
        actions = np.array([[rng.choice(np.flatnonzero(robot_mask)) for robot_mask in copy] for copy in masks])
        requests = [
            {} if restarting[copy] else dict(zip(adapter.agents, actions[copy].tolist())) for copy in range(COPIES)
        ]
        observations, rewards, terminateds, truncateds, infos = adapter.step(requests)
        reference_observations, reference_rewards, terminated, truncated, _ = reference.step(actions)
        _assert_copies_equal(adapter, observations, reference_observations, reference.action_masks())
        for copy in range(COPIES):
            assert rewards[copy] == dict(zip(adapter.agents, reference_rewards[copy].tolist()))
            assert terminateds[copy] == {
                **dict(zip(adapter.agents, terminated[copy].tolist())),
                ALL: terminated[copy, 0],
            }
            assert truncateds[copy] == {**dict(zip(adapter.agents, truncated[copy].tolist())), ALL: truncated[copy, 0]}
            if restarting[copy]:  # the step after an end: the copy's reset observations, no reward, running
                assert set(rewards[copy].values()) == {0.0} and not terminateds[copy][ALL] | truncateds[copy][ALL]
                singles[copy].reset()
                episodes[copy] = []
            else:
                episodes[copy].append(singles[copy].step(dict(zip(adapter.agents, actions[copy].tolist())))[-1])
            if terminated[copy, 0] or truncated[copy, 0]:  # the episode's main metric, for the learning curve
                metric = main_metric_of(singles[copy]).compute(episodes[copy])
                assert infos[copy] == {agent: {METRIC_KEY: metric} for agent in adapter.agents}
            else:
                assert infos[copy] == {}
        restarting = terminated[:, 0] | truncated[:, 0]
        end_steps.extend((step, copy) for copy in np.flatnonzero(restarting).tolist())
    assert end_steps  # every copy's episode ended at least once ...
    assert {copy for _, copy in end_steps} == set(range(COPIES))
    if "coverage_target" in config:  # ... and, here, copies ended at different steps
        steps_by_copy = {copy: {step for step, ended in end_steps if ended == copy} for copy in range(COPIES)}
        assert len({frozenset(steps) for steps in steps_by_copy.values()}) > 1


def test_the_adapter_refuses_a_missing_action_and_another_autoreset_mode():
    adapter, _ = _pair(*TEAM_CONFIGS[0])
    adapter.reset(seed=0)
    with pytest.raises(ValueError, match="copy 1 has no action for robot_2"):
        adapter.step([dict.fromkeys(adapter.agents, 0), {"robot_0": 0, "robot_1": 0}, *[{}] * (COPIES - 2)])
    with pytest.raises(ValueError, match=f"one {{robot: action}} dict per copy \\({COPIES}\\), got 1"):
        adapter.step([dict.fromkeys(adapter.agents, 0)])
    same_step = make_vector_env("cooperative_localization_v0", 2, autoreset_mode=AutoresetMode.SAME_STEP)
    with pytest.raises(ValueError, match="NEXT_STEP autoreset"):
        BatchedTeamEnv(same_step)
