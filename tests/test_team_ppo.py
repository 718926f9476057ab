"""Parameter-shared PPO on cooperative_localization_v0: the TeamVecEnv adapter, training and evaluating it."""

import math

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

from sb3_contrib.common.maskable.utils import get_action_masks, is_masking_supported  # noqa: E402

from agents.ppo import PPOAgent, train  # noqa: E402
from agents.team_vec_env import RobotSlots, TeamVecEnv, make_team_vec_env  # noqa: E402
from infonav_gym.experiments.evaluation import evaluate  # noqa: E402
from infonav_gym.experiments.training_timing import sb3_train_steps_per_s, training_block  # noqa: E402
from infonav_gym.multi import cooperative_localization_v0  # noqa: E402
from infonav_gym.registry import make_vector_env  # noqa: E402

# PPO training: slow; `pytest -m "not slow"` leaves it out while developing
pytestmark = pytest.mark.slow

TEAM_ENV = "cooperative_localization_v0"
CONFIG = {"max_cycles": 6}
N_ROBOTS = 4  # the default team


def valid_random_actions(masks: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return np.array([rng.choice(np.flatnonzero(mask)) for mask in masks])


def test_every_robot_of_every_copy_is_one_slot_with_the_robots_spaces():
    vec_env = TeamVecEnv(3, seed=0, env_kwargs=CONFIG)
    team = cooperative_localization_v0.parallel_env(**CONFIG)
    assert vec_env.num_envs == 3 * N_ROBOTS
    assert vec_env.observation_space == team.observation_space("robot_0")
    assert vec_env.action_space == team.action_space("robot_0") == gym.spaces.Discrete(N_ROBOTS + 1)
    observations = vec_env.reset()
    assert observations.shape == (3 * N_ROBOTS, *vec_env.observation_space.shape) and observations.dtype == np.float32
    assert all(vec_env.observation_space.contains(observation) for observation in observations)
    assert vec_env.action_masks().shape == (3 * N_ROBOTS, N_ROBOTS + 1) and vec_env.action_masks().dtype == bool
    assert vec_env.get_attr("agent", indices=[0, 5, 11]) == ["robot_0", "robot_1", "robot_3"]


def test_slots_replay_copies_seeded_seed_plus_i_with_masks_rewards_and_automatic_resets():
    """Copy i of the vec env and a parallel env reset with seed + i, stepped alike, agree step for step."""
    n_envs, seed, max_cycles = 2, 11, CONFIG["max_cycles"]
    vec_env = TeamVecEnv(n_envs, seed=seed, env_kwargs=CONFIG)
    references = [cooperative_localization_v0.parallel_env(**CONFIG) for _ in range(n_envs)]
    agents = references[0].possible_agents
    expected = [env.reset(seed=seed + copy) for copy, env in enumerate(references)]
    observations, rng, episode_ends = vec_env.reset(), np.random.default_rng(0), 0
    for step in range(max_cycles + 3):
        masks = vec_env.action_masks()
        np.testing.assert_array_equal(get_action_masks(vec_env), masks)  # what MaskablePPO asks for
        actions = valid_random_actions(masks, rng)
        for copy, (reference_observations, reference_infos) in enumerate(expected):
            for k, agent in enumerate(agents):
                slot = copy * N_ROBOTS + k
                np.testing.assert_array_equal(observations[slot], reference_observations[agent])
                np.testing.assert_array_equal(masks[slot], reference_infos[agent]["action_mask"].astype(bool))
        observations, rewards, dones, infos = vec_env.step(actions)
        for copy, env in enumerate(references):
            team_actions = {agent: int(actions[copy * N_ROBOTS + k]) for k, agent in enumerate(agents)}
            reference_observations, reference_rewards, _, truncations, reference_infos = env.step(team_actions)
            for k, agent in enumerate(agents):
                slot = copy * N_ROBOTS + k
                assert rewards[slot] == np.float32(reference_rewards[agent])
                assert dones[slot] == truncations[agent] == (step + 1 == max_cycles)
                step_info = vec_env.vector_env.team_info["final_info"] if dones[slot] else vec_env.vector_env.team_info
                assert step_info["chosen_action"][copy, k] == actions[slot]
                if dones[slot]:
                    assert infos[slot]["TimeLimit.truncated"]
                    np.testing.assert_array_equal(infos[slot]["terminal_observation"], reference_observations[agent])
                else:
                    assert infos[slot] == {}  # SB3 needs nothing more of a slot that goes on
            if not env.agents:
                episode_ends += 1
                reference_observations, reference_infos = env.reset()  # unseeded: continues its generator
            expected[copy] = (reference_observations, reference_infos)
    assert episode_ends == n_envs
    assert 0 < masks[:, 1:].sum() < masks[:, 1:].size, "some teammates observable, not all: the masks matter"


def test_same_seed_same_rollout_and_sb3_seed_call_seeds_the_copies():
    def rollout(vec_env: TeamVecEnv) -> list[np.ndarray]:
        rng, record = np.random.default_rng(1), [vec_env.reset()]
        for _ in range(2 * CONFIG["max_cycles"]):
            observations, rewards, dones, _ = vec_env.step(valid_random_actions(vec_env.action_masks(), rng))
            record += [observations, rewards, dones, vec_env.action_masks()]
        return record

    first, second = rollout(TeamVecEnv(2, seed=3, env_kwargs=CONFIG)), rollout(TeamVecEnv(2, seed=3, env_kwargs=CONFIG))
    for a, b in zip(first, second, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(first[0], rollout(TeamVecEnv(2, seed=4, env_kwargs=CONFIG))[0])
    unseeded = TeamVecEnv(2, seed=None, env_kwargs=CONFIG)
    assert unseeded.seed(3) == [3] * N_ROBOTS + [4] * N_ROBOTS  # what MaskablePPO(seed=3) calls
    np.testing.assert_array_equal(unseeded.reset(), first[0])


def test_attributes_methods_and_masks_reach_the_right_copy_and_robot():
    vec_env = make_team_vec_env(2, seed=0, env_kwargs=CONFIG)  # under VecMonitor, as in training
    vec_env.reset()
    assert is_masking_supported(vec_env)
    masks = vec_env.unwrapped.action_masks()
    np.testing.assert_array_equal(np.stack(vec_env.env_method("action_masks", indices=[3, 6])), masks[[3, 6]])
    assert vec_env.env_is_wrapped(gym.Wrapper) == [False] * 2 * N_ROBOTS
    assert vec_env.get_attr("max_cycles") == [CONFIG["max_cycles"]] * 2 * N_ROBOTS
    with pytest.raises(
        ValueError, match=r"set_attr\('max_cycles'\) .* acts on every sub-env: pass indices=None, got \[4\]"
    ):
        vec_env.set_attr("max_cycles", 2, indices=[N_ROBOTS])
    vec_env.set_attr("max_cycles", 2)  # the batched env's, for every copy
    for _ in range(2):
        _, _, dones, infos = vec_env.step(np.zeros(2 * N_ROBOTS, dtype=int))
    assert dones.tolist() == [True] * 2 * N_ROBOTS
    assert all(info["episode"]["l"] == 2 for info in infos)  # VecMonitor's per-robot episode record
    with pytest.raises(ValueError, match=r"one action per slot, shape \(8,\), got shape \(3,\)"):
        vec_env.step(np.zeros(3, dtype=int))
    with pytest.raises(ValueError, match="n_envs must be >= 1, got 0"):
        TeamVecEnv(0)


def test_robot_slots_seed_each_copy_once_for_all_its_robots():
    slots = RobotSlots(make_vector_env(TEAM_ENV, 2, autoreset_mode="same_step", **CONFIG))
    observations, _ = slots.reset(seed=[3] * N_ROBOTS + [4] * N_ROBOTS)
    np.testing.assert_array_equal(observations, TeamVecEnv(2, seed=3, env_kwargs=CONFIG).reset())
    with pytest.raises(ValueError, match=r"one seed per slot \(8\), the same for the 4 robots of a copy"):
        slots.reset(seed=[3, 3, 3, 4, 4, 4, 4, 4])
    with pytest.raises(ValueError, match=r"one action per slot, shape \(8,\), got shape \(2, 4\)"):
        slots.step(np.zeros((2, N_ROBOTS), dtype=int))


# small, explicit hyperparameters: the tuned block of agents/hyperparams/ppo.yml trains for minutes
TEAM_HYPERPARAMETERS = {"n_steps": 128, "batch_size": 256, "gamma": 0.9, "normalize": {"norm_obs": True}}


@pytest.fixture(scope="module")
def team_model(tmp_path_factory) -> dict:
    """One parameter-shared MaskablePPO trained one rollout: 1,024 robot steps (2 copies x 4 robots x 128)."""
    output = tmp_path_factory.mktemp("team_ppo")
    path = train(
        TEAM_ENV,
        2 * N_ROBOTS * 128,
        n_envs=2,
        output_dir=output,
        env_kwargs={"max_cycles": 20},
        progress=False,
        hyperparameters=TEAM_HYPERPARAMETERS,
    )
    return {"path": str(path), "output": output}


def test_train_on_the_team_env_shares_one_maskable_policy_over_the_robots(team_model):
    import json

    record = json.loads((team_model["output"] / "train.json").read_text())
    assert record["algorithm"] == "MaskablePPO" and record["env_id"] == TEAM_ENV
    assert record["n_envs"] == 2 * N_ROBOTS and record["timesteps"] == 2 * N_ROBOTS * 128
    assert record["hyperparameters"] == {**TEAM_HYPERPARAMETERS, "n_envs": 2}
    assert (team_model["output"] / "vecnormalize.pkl").is_file()


def test_each_robot_acts_with_the_shared_policy_only_among_its_valid_actions(team_model):
    env = cooperative_localization_v0.parallel_env(max_cycles=30)
    robots = {agent: PPOAgent(team_model["path"], env, agent=agent) for agent in env.possible_agents}
    observations, infos = env.reset(seed=5)
    while env.agents:
        actions = {agent: robots[agent].act(observations[agent], infos[agent]) for agent in env.agents}
        assert all(infos[agent]["action_mask"][action] for agent, action in actions.items())
        observations, _, _, _, infos = env.step(actions)
    with pytest.raises(ValueError, match=r"trained for observations \(30,\).*env \(robot_0\) has \(25,\)"):
        PPOAgent(team_model["path"], cooperative_localization_v0.parallel_env(n_robots=3), agent="robot_0")


def test_evaluate_the_team_with_ppo_is_finite_and_reproducible(team_model):
    names = ["random", "ppo:" + team_model["path"]]
    kwargs = {"env_kwargs": {"max_cycles": 20}, "progress": False}
    first, second = evaluate(TEAM_ENV, names, episodes=2, **kwargs), evaluate(TEAM_ENV, names, episodes=2, **kwargs)
    assert first == second and list(first["agents"]) == names
    for result in first["agents"].values():
        values = [episode[key] for episode in result["episodes"] for key in first["metrics"]]
        assert len(values) == 2 * 3 and all(math.isfinite(value) for value in values)
        assert all(episode["cumulative_mi"] > 0 for episode in result["episodes"])
    with pytest.raises(ValueError, match="agent 'planner' is not available for cooperative_localization_v0"):
        evaluate(TEAM_ENV, ["planner"], episodes=1, **kwargs)


@pytest.mark.slow  # a fresh exploration model: its kernels and two short rollouts
def test_the_benchmarks_sb3_training_rate_trains_the_shipped_block_on_fewer_copies():
    block = training_block(n_envs=2)  # a rollout of 2 copies x 64 steps x 4 robots, minibatches at most 128
    assert block["n_envs"] == 2 and block["batch_size"] == 128 and isinstance(block["learning_rate"], float)
    assert sb3_train_steps_per_s(n_envs=2, iterations=1) > 0
