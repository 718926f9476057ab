"""cooperative_exploration_v0's planning model against raw filterpy, and the decentralized planner on it."""

import math

import filterpy_reference as oracle
import numpy as np
import pytest
from conftest import map_footprints
from team_vector_checks import exploration_observation_updates

from agents import PlannerAgent
from agents.team_planning import TeamPlans
from infonav_gym.envs.cooperative_exploration.exploration_planning import MOTION_HEADINGS_RAD, N_MOTIONS, STAY
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.information import largest_position_std
from infonav_gym.multi import cooperative_exploration_v0, cooperative_localization_v0

FAST = {"rollout_steps": 4, "detour_steps": (0,)}  # short rollouts: the tests check behaviour, not quality


def expected_step_by_hand(env, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Raw filterpy at the env's state stepped through ``actions`` (R,) with every measurement as
    predicted and the commanded odometry: ``(P after the step, each robot's reward)``, the DGPS robots all outside
    canopies."""
    cfg, parts = env.config, env.vector.parts
    ekf = oracle.filterpy_filter(*(part[0] for part in env.vector.joint_state()))
    map_variances = env.vector.map_variances[0]
    slots, motions = np.divmod(actions, N_MOTIONS)
    prior_log_dets = np.linalg.slogdet(oracle.pose_blocks(ekf.P))[1]
    exploration_observation_updates(ekf, env, slots)
    own = 0.5 * (prior_log_dets - np.linalg.slogdet(oracle.pose_blocks(ekf.P))[1])
    drives = motions != STAY
    headings = env.vector.joint_state()[0][0, 2::POSE_DIM]  # the decision's
    turns = np.where(drives, (MOTION_HEADINGS_RAD[motions] - headings + math.pi) % (2 * math.pi) - math.pi, 0.0)
    speeds = np.where(drives, parts.speeds_mps, 0.0)
    turn_s, drive_s = cfg["turn_time_s"], cfg["time_step_s"] - cfg["turn_time_s"]
    covariances = np.repeat(parts.odometry.noise_covariance()[None], len(actions), axis=0)
    oracle.filterpy_predict(ekf, np.column_stack([np.zeros_like(turns), turns / turn_s]), covariances, turn_s)
    oracle.filterpy_predict(ekf, np.column_stack([speeds, np.zeros_like(speeds)]), covariances, drive_s)
    fixed, n = np.flatnonzero([gps is not None for gps in parts.gps]), len(ekf.x)
    H, R = oracle.gps_jacobian(fixed, n), oracle.block_diagonal([parts.gps[k].noise_covariance() for k in fixed])
    oracle.filterpy_update(ekf, H @ ekf.x, H @ ekf.x, H, R, [], n // POSE_DIM)
    poses = ekf.x.reshape(-1, POSE_DIM)
    position_std = largest_position_std(oracle.pose_blocks(ekf.P))
    footprints = map_footprints(parts.map_model, poses[drives, :2])
    noise = parts.map_model.scan_noise_variances(position_std[drives])
    after = 1.0 / (1.0 / map_variances + np.sum(footprints / noise[:, None], axis=0))
    map_information = 0.5 * np.sum(np.log(map_variances / after))
    weight = cfg["team_reward"]
    costs = cfg["observation_cost_nats"] * (slots > 0) + cfg["motion_cost_per_step"] * drives
    return ekf.P, (1 - weight) * own + weight * map_information - costs


def assert_model_step_is_the_filters(env, actions: np.ndarray):
    """The model's step of ``actions`` (R,) from the current belief gives ``expected_step_by_hand``'s numbers."""
    model = env.planning_model()
    belief = model.belief()
    assert belief.motion_clear[0, np.arange(4), actions % N_MOTIONS].all(), "clear from the estimates too"
    following, rewards = model.plan_step(belief, actions[None])
    P, expected = expected_step_by_hand(env, actions)
    np.testing.assert_allclose(following.covariance[0], P, rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(rewards[0], expected, rtol=1e-9)
    return following


def test_one_model_step_is_filterpys_joint_ekf_on_predicted_measurements_and_commanded_motion():
    env = cooperative_exploration_v0.parallel_env()
    _, infos = env.reset(seed=0)
    n_landmarks = env.config["n_landmarks"]
    robot_2_sees_robot_0 = N_MOTIONS * (1 + n_landmarks + 0) + 2  # and drives north
    robot_1_sees_robot_3 = N_MOTIONS * (1 + n_landmarks + 3) + 1  # and drives east
    actions = np.array([3, robot_1_sees_robot_3, robot_2_sees_robot_0, 4])
    assert all(infos[agent]["action_mask"][action] for agent, action in zip(env.agents, actions))
    following = assert_model_step_is_the_filters(env, actions)
    assert following.steps.tolist() == [1] and following.observations_left[0].tolist() == [100, 99, 99, 100]


def test_a_model_step_with_landmark_and_teammate_observations_matches_filterpys_joint_ekf_too():
    env = cooperative_exploration_v0.parallel_env()
    _, infos = env.reset(seed=10)  # every robot sees landmark 0 from the base
    landmark_0, robot_3 = N_MOTIONS * 1, N_MOTIONS * (1 + env.config["n_landmarks"] + 3)
    actions = np.array([landmark_0 + 1, landmark_0, robot_3 + 3, landmark_0 + 2])  # east, stay, west, north
    assert all(infos[agent]["action_mask"][action] for agent, action in zip(env.agents, actions))
    assert_model_step_is_the_filters(env, actions)


def test_the_models_decision_at_the_current_belief_gives_the_envs_gains():
    env = cooperative_exploration_v0.parallel_env()
    _, infos = env.reset(seed=1)
    rng, model = np.random.default_rng(1), env.planning_model()
    agree, checked = [], 0
    for _ in range(12):
        belief = model.belief()
        for robot, agent in enumerate(env.agents):
            mask, gains = model.plan_decision(belief, robot)
            both = (mask[0] > 0) & (infos[agent]["action_mask"] > 0)
            np.testing.assert_allclose(gains[0][both], infos[agent]["action_information_gain"][both], atol=1e-12)
            agree.append(np.mean(mask[0] == infos[agent]["action_mask"]))
            checked += both.sum()
        actions = {a: int(rng.choice(np.flatnonzero(info["action_mask"]))) for a, info in infos.items()}
        _, _, _, _, infos = env.step(actions)
    assert checked > 500 and np.mean(agree) > 0.97  # the model sees from the estimates, the env from the truth


def test_team_plans_give_each_teammate_the_plan_it_published_before_this_step():
    plans = TeamPlans(3)
    plans.publish(0, 3, [10, 11, 12])
    plans.publish(1, 4, [20, 21])
    assert plans.actions_at(4, np.array([0, 1, 5]), 0).tolist() == [[11, 0, 0], [12, 0, 0], [0, 0, 0]]
    plans.publish(0, 4, [30, 31])  # made at step 4: teammates see it from step 5
    assert plans.actions_at(4, np.array([0]), 0).tolist() == [[11, 0, 0]]
    assert plans.actions_at(5, np.array([0]), 0).tolist() == [[31, 21, 0]]
    plans.clear(0)
    assert plans.actions_at(5, np.array([0]), 0).tolist() == [[0, 21, 0]]


def run_planners(seed: int, steps: int) -> list[dict]:
    env = cooperative_exploration_v0.parallel_env()
    planners = {agent: PlannerAgent(env, agent, **FAST) for agent in env.possible_agents}
    observations, infos = env.reset(seed=seed)
    for planner in planners.values():
        planner.reset(seed)
    chosen = []
    for _ in range(steps):
        actions = {agent: planners[agent].act(observations[agent], infos[agent]) for agent in env.agents}
        for agent, action in actions.items():
            assert infos[agent]["action_mask"][action], f"{agent} chose masked action {action}"
        observations, _, _, _, infos = env.step(actions)
        assert not any(info["invalid_action"] for info in infos.values())
        chosen.append(actions)
    return chosen


def test_the_team_planner_is_deterministic_and_respects_the_masks():
    first = run_planners(4, 8)
    assert first == run_planners(4, 8)
    assert any(action % N_MOTIONS != STAY for actions in first for action in actions.values())


def test_the_planner_never_picks_an_action_the_current_mask_forbids():
    env = cooperative_exploration_v0.parallel_env()
    observations, infos = env.reset(seed=0)
    planner = PlannerAgent(env, "robot_3", **FAST)
    info = dict(infos["robot_3"])
    mask = info["action_mask"].copy()
    preferred = planner.act(observations["robot_3"], info)
    mask[preferred] = 0
    mask[preferred - preferred % N_MOTIONS] = 1  # its observation, standing still, stays allowed
    action = planner.act(observations["robot_3"], {**info, "action_mask": mask})
    assert action != preferred and mask[action]


def test_the_planner_in_a_team_env_needs_a_robot_and_a_planning_model():
    env = cooperative_exploration_v0.parallel_env()
    with pytest.raises(ValueError, match=r"needs agent=ROBOT, one of \['robot_0'"):
        PlannerAgent(env)
    with pytest.raises(ValueError, match="unknown agent 'robot_9'"):
        PlannerAgent(env, "robot_9")
    with pytest.raises(ValueError, match=r"planning_model\(\) method"):
        PlannerAgent(cooperative_localization_v0.parallel_env(), "robot_0")
    with pytest.raises(RuntimeError, match="call reset"):
        env.planning_model().belief()
