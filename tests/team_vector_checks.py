"""The shared checks of a team env's native vector env: copy i equals the parallel env seeded seed + i.

What a check expects comes from the vector env (``agents``, ``team_info_keys``, ``action_masks()``) and the
parallel env's outputs, never from the env's id.
"""

from __future__ import annotations

import numpy as np
import pytest
from filterpy_reference import angle_rows, block_diagonal, filterpy_update, range_bearing, relative_pose, stacked

from infonav_gym.multi import team_scenario
from infonav_gym.registry import env_entry
from infonav_gym.sensors.relative_pose import noise_covariances, relative_poses_with_noise

TOLERANCE = 1e-9


def team_envs(env_id: str) -> tuple:
    """The parallel env class and the native vector env class of the registered team env ``env_id``."""
    entry = env_entry(env_id)
    return entry.load(), entry.load_vector()


def record_relative_measurements(monkeypatch) -> list:
    """The relative poses each ``relative_updates`` call measures (n, R, 3) (zeros where a robot observes no one),
    computed by the sensor's ``relative_poses_with_noise`` from the call's truth, sensor and standard normals."""
    measurements = []
    updates = team_scenario.relative_updates

    def recorded(x, P, chosen, pair_index, targets, parameters, geometry, *rest):
        noise, measured = rest[-2], np.zeros(rest[-2].shape)
        for copy, robot in np.argwhere(pair_index[np.arange(chosen.shape[1]), chosen] >= 0):
            pair = pair_index[robot, chosen[copy, robot]]
            measured[copy, robot] = relative_poses_with_noise(
                geometry[copy, pair][None], parameters[pair], noise[copy, robot][None]
            )[0]
        measurements.append(measured)
        return updates(x, P, chosen, pair_index, targets, parameters, geometry, *rest)

    monkeypatch.setattr(team_scenario, "relative_updates", recorded)
    return measurements


def assert_copy_equals(observations, info, copy: int, reference: tuple, team_keys) -> None:
    """Copy ``copy`` of the vector env's observations and info equal the parallel env's ``(observations, infos)``.

    ``team_keys`` are the info keys the vector env gives per copy (N,), not per copy and robot.
    """
    reference_observations, reference_infos = reference
    for robot, agent in enumerate(reference_infos):
        np.testing.assert_allclose(observations[copy][robot], reference_observations[agent], rtol=0, atol=1e-6)
        for key, expected in reference_infos[agent].items():
            assert info[f"_{key}"][copy], key
            got = info[key][copy] if key in team_keys else info[key][copy, robot]
            np.testing.assert_allclose(got, expected, rtol=0, atol=TOLERANCE, err_msg=f"{key} of {agent}, copy {copy}")


def random_valid(masks: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    return np.array([[rng.choice(np.flatnonzero(robot)) for robot in copy] for copy in masks])


def greedy(masks: np.ndarray, info: dict) -> np.ndarray:
    return np.argmax(np.where(masks, info["action_information_gain"], -1.0), axis=-1)


def run_against_parallel_envs(env_id: str, config: dict, n_copies: int, seed: int, policy, steps: int) -> dict:
    """Step the vector env and one parallel env per copy alike (NEXT_STEP) for ``steps``; every number must agree.

    Args:
        env_id: a registered team env with a native vector env.
        config: its config.
        n_copies: N.
        seed: the vector env's reset seed (copy i: the parallel env's ``reset(seed=seed + i)``).
        policy: ``"random"`` (valid actions), ``"greedy"`` (best ``action_information_gain``), or ``"mixed"``
            (greedy, random every third step).
        steps: vector steps after the reset.

    Returns:
        How many episodes ended ``{"terminated": ..., "truncated": ...}``.
    """
    parallel_class, vector_class = team_envs(env_id)
    vector = vector_class(n_copies, autoreset_mode="next_step", **config)
    references = [parallel_class(**config) for _ in range(n_copies)]
    observations, info = vector.reset(seed=seed)
    team_keys = vector.team_info_keys
    for copy, env in enumerate(references):
        assert_copy_equals(observations, info, copy, env.reset(seed=seed + copy), team_keys)
    rng, ended = np.random.default_rng(seed), {"terminated": 0, "truncated": 0}
    for step in range(steps):
        masks = vector.action_masks()
        np.testing.assert_array_equal(masks, info["action_mask"].astype(bool))
        randomly = policy == "random" or (policy == "mixed" and step % 3 == 0)
        actions = random_valid(masks, rng) if randomly else greedy(masks, info)
        observations, rewards, terminations, truncations, info = vector.step(actions)
        for copy, env in enumerate(references):
            if not env.agents:  # the copy resets in this step (NEXT_STEP): its actions are ignored
                assert_copy_equals(observations, info, copy, env.reset(), team_keys)
                assert not rewards[copy].any() and not truncations[copy].any() and not terminations[copy].any()
                continue
            step_outputs = env.step(
                {agent: int(actions[copy, robot]) for robot, agent in enumerate(env.possible_agents)}
            )
            reference_observations, reference_rewards, reference_terminations, reference_truncations, infos = (
                step_outputs
            )
            assert_copy_equals(observations, info, copy, (reference_observations, infos), team_keys)
            for robot, agent in enumerate(env.possible_agents):
                assert rewards[copy, robot] == pytest.approx(reference_rewards[agent], abs=TOLERANCE)
                assert terminations[copy, robot] == reference_terminations[agent]
                assert truncations[copy, robot] == reference_truncations[agent]
            ended["terminated"] += bool(terminations[copy, 0])
            ended["truncated"] += bool(truncations[copy, 0])
    return ended


def exploration_observation_updates(ekf, env, slots: np.ndarray, relative=None, landmarks=None) -> tuple[int, int]:
    """Fuse into raw filterpy ``ekf`` (``filterpy_reference``) the observations of one step of a
    cooperative_exploration_v0 view ``env`` whose robots chose observation ``slots`` (R,): the teammates' relative
    poses ``relative`` (R, 3), then the landmarks' range-bearing ``landmarks`` (R, 2) (None: each as predicted).
    Returns how many of each."""
    parts, n_landmarks, n_robots = env.vector.parts, env.config["n_landmarks"], len(slots)
    observers = np.flatnonzero(slots > n_landmarks)
    if observers.size:
        targets = slots[observers] - 1 - n_landmarks
        predicted, H = stacked([relative_pose(ekf.x, o, t) for o, t in zip(observers, targets)])
        pairs = [
            np.flatnonzero((parts.pairs.observers == i) & (parts.pairs.targets == j))[0]
            for i, j in zip(observers, targets)
        ]
        R = block_diagonal(noise_covariances(parts.pairs.noise[pairs], predicted[0::3]))
        measured = predicted if relative is None else relative[observers].ravel()
        filterpy_update(ekf, measured, predicted, H, R, angle_rows(observers.size, 3), n_robots)
    robots = np.flatnonzero((slots > 0) & (slots <= n_landmarks))
    if robots.size:
        positions = env.vector.scenario(0).landmarks[slots[robots] - 1]
        predicted, H = stacked([range_bearing(ekf.x, robot, position) for robot, position in zip(robots, positions)])
        sensors = [parts.relative_sensors[robot].range_bearing for robot in robots]
        R = block_diagonal([sensor.noise_covariance(predicted[2 * k])[0] for k, sensor in enumerate(sensors)])
        measured = predicted if landmarks is None else landmarks[robots].ravel()
        filterpy_update(ekf, measured, predicted, H, R, angle_rows(robots.size, 2), n_robots)
    return observers.size, robots.size
