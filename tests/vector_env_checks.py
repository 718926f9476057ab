"""The shared checks of a native infonav vector env (an id registered with a ``vector_entry_point``).

Each ``check_*`` takes the env id and config; what it expects comes from the env's spaces and infos, never
from its id: a ``Discrete`` single action space, ``info["action_mask"]`` (N, A), ``np_randoms``, the
``autoreset_mode`` argument (``NEXT_STEP`` / ``SAME_STEP``), infos as dicts of arrays with ``_key`` masks.
The checks compare with Gymnasium's own ``SyncVectorEnv`` of the single env wherever it defines the answer.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from env_checks import WALL_CLOCK_INFO_KEYS, without_wall_clock
from filterpy_reference import filterpy_filter, filterpy_predict, filterpy_update, range_bearing
from gymnasium.utils.env_checker import data_equivalence
from gymnasium.vector import AutoresetMode
from gymnasium.wrappers.vector import DictInfoToList, RecordEpisodeStatistics

import infonav_gym  # noqa: F401  (registers the envs)
from infonav_gym.envs.vector_infos import REWARD_TERM_PREFIX, REWARD_TERMS_KEY, reward_term_key, reward_terms_of
from infonav_gym.information import mutual_information

TOLERANCE = 1e-9


def some_actions(rng: np.random.Generator, info: dict) -> np.ndarray:
    """Per sub-env: a random valid action (by ``info["action_mask"]``) or, one time in three, any action."""
    mask = info["action_mask"]
    valid = np.array([rng.choice(np.flatnonzero(row)) if row.any() else 0 for row in mask])
    return np.where(rng.random(len(mask)) < 2 / 3, valid, rng.integers(0, mask.shape[1], len(mask)))


def assert_info_entry_equal(actual, expected, where: str) -> None:
    """An info entry equals the expected one: to ``TOLERANCE`` for numbers, exactly for others (a str, an object array
    of them, as Gymnasium's ``SyncVectorEnv`` stacks them)."""
    if np.asarray(expected).dtype.kind in "biufc":
        np.testing.assert_allclose(actual, expected, rtol=0, atol=TOLERANCE, err_msg=where)
    else:
        np.testing.assert_array_equal(actual, expected, err_msg=where)


def flat_info(info: dict) -> dict:
    """A single env's ``info`` with its ``reward_terms`` flat, as a vector env's infos hold them."""
    terms = {reward_term_key(term): value for term, value in info.get(REWARD_TERMS_KEY, {}).items()}
    return {**{key: value for key, value in info.items() if key != REWARD_TERMS_KEY}, **terms}


def assert_sub_env_info_matches(vector_info: dict, copy: int, single_info: dict, where: str) -> None:
    """Every key of the single env's info equals the sub-env's entry (a reward term within ``TOLERANCE``), which its
    ``_key`` mask marks as present."""
    single_info = flat_info(single_info)
    assert set(vector_info) == set(single_info) | {f"_{key}" for key in single_info}, where
    terms = reward_terms_of(single_info)
    for key, value in single_info.items():
        assert vector_info[f"_{key}"][copy], f"{where}: _{key}"
        if key in WALL_CLOCK_INFO_KEYS:
            continue
        if key.removeprefix(REWARD_TERM_PREFIX) in terms:
            assert abs(vector_info[key][copy] - value) <= TOLERANCE, f"{where}: {key}"
        else:
            assert_info_entry_equal(vector_info[key][copy], value, f"{where}: {key}")


def assert_step_matches(outputs: tuple, copy: int, single_outputs: tuple, where: str) -> None:
    """Sub-env ``copy``'s (observation, reward, terminated, truncated, info) equals the single env's."""
    observation, reward, terminated, truncated, info = single_outputs
    np.testing.assert_allclose(outputs[0][copy], observation, rtol=0, atol=TOLERANCE, err_msg=where)
    assert abs(outputs[1][copy] - reward) <= TOLERANCE, where
    assert (outputs[2][copy], outputs[3][copy]) == (terminated, truncated), where
    assert_sub_env_info_matches(outputs[4], copy, info, where)


def _without_final(info: dict) -> dict:
    return {key: value for key, value in info.items() if not key.lstrip("_").startswith("final_")}


def run_in_lockstep(
    env_id: str, n_envs: int, seed: int, n_steps: int, choose_actions, mode=AutoresetMode.NEXT_STEP, **config
) -> tuple[int, int]:
    """Step the vector env and N single envs (seeds ``seed + i``) together; every number must agree.

    A sub-env's autoreset is the single env's ``reset()`` without a seed: with ``NEXT_STEP`` at the next step
    (reward 0), with ``SAME_STEP`` in the step that ended the episode, whose outputs are then ``final_obs`` and
    ``final_info``.

    Args:
        env_id: the registered id.
        n_envs: N.
        seed: the vector env's reset seed.
        n_steps: steps after the reset.
        choose_actions: ``(rng, info) -> actions (N,)``.
        mode: the autoreset mode.
        config: the env config.

    Returns:
        How many episodes ended terminated, and how many truncated.
    """
    vector = gym.make_vec(env_id, num_envs=n_envs, autoreset_mode=mode, **config)
    singles = [gym.make(env_id, **config) for _ in range(n_envs)]
    observations, info = vector.reset(seed=seed)
    no_step = np.zeros(n_envs, dtype=bool)
    for copy, single in enumerate(singles):
        single_observation, single_info = single.reset(seed=seed + copy)
        outputs = (observations, np.zeros(n_envs), no_step, no_step, info)
        assert_step_matches(outputs, copy, (single_observation, 0.0, False, False, single_info), f"sub-env {copy}")
    done, rng, ended = no_step, np.random.default_rng(seed), np.zeros(2, dtype=int)
    for step in range(1, n_steps + 1):
        actions = choose_actions(rng, info)
        outputs = vector.step(actions)
        ending = outputs[2] | outputs[3]
        if mode == AutoresetMode.SAME_STEP:
            assert ("_final_obs" in outputs[4]) == ending.any(), f"step {step}"  # as SyncVectorEnv
        for copy, single in enumerate(singles):
            where = f"sub-env {copy}, step {step}"
            if done[copy]:  # NEXT_STEP: this step resets the sub-env
                observation, single_info = single.reset()
                single_outputs = (observation, 0.0, False, False, single_info)
            else:
                single_outputs = single.step(actions[copy])
            if mode == AutoresetMode.SAME_STEP and ending[copy]:
                final = outputs[4]
                np.testing.assert_allclose(final["final_obs"][copy], single_outputs[0], atol=TOLERANCE, err_msg=where)
                assert_sub_env_info_matches(final["final_info"], copy, single_outputs[4], where)
                observation, single_info = single.reset()
                single_outputs = (observation, *single_outputs[1:4], single_info)
            elif mode == AutoresetMode.SAME_STEP and ending.any():
                assert outputs[4]["final_obs"][copy] is None and not outputs[4]["_final_info"][copy], where
            assert_step_matches((*outputs[:4], _without_final(outputs[4])), copy, single_outputs, where)
        ended += [outputs[2].sum(), outputs[3].sum()]
        done = ending if mode == AutoresetMode.NEXT_STEP else no_step
        info = outputs[4]
    vector.close()
    return int(ended[0]), int(ended[1])


def _flat_vector_info(info: dict) -> dict:
    """A ``SyncVectorEnv`` info of single envs with its ``reward_terms`` (a dict with ``_term`` masks) flat, as the
    native vector env's: ``reward_term`` and its ``_reward_term`` mask."""
    if REWARD_TERMS_KEY not in info:
        return info
    terms, flat = info[REWARD_TERMS_KEY], {}
    for term, value in terms.items():
        flat["_" + reward_term_key(term[1:]) if term[0] == "_" else reward_term_key(term)] = value
    return {key: value for key, value in info.items() if key.lstrip("_") != REWARD_TERMS_KEY} | flat


def _assert_infos_match(native: dict, sync: dict, where: str) -> None:
    """The native info holds every entry of the ``SyncVectorEnv`` info (its reward terms flat); its other entries
    are masked out."""
    sync = _flat_vector_info(sync)
    for key, value in sync.items():
        if isinstance(value, dict):
            _assert_infos_match(native[key], value, f"{where}: {key}")
        elif key == "final_obs":
            assert [row is None for row in native[key]] == [row is None for row in value], where
            for native_row, sync_row in zip(native[key], value):
                if sync_row is not None:
                    np.testing.assert_allclose(native_row, sync_row, rtol=0, atol=TOLERANCE, err_msg=where)
        elif key not in WALL_CLOCK_INFO_KEYS:
            assert_info_entry_equal(native[key], value, f"{where}: {key}")
    for key in set(native) - set(sync):  # e.g. reward terms of sub-envs that were reset (a reset info has none)
        assert not native[f"_{key.lstrip('_')}"].any(), f"{where}: {key}"


def check_matches_sync_vectorization(env_id: str, mode: AutoresetMode, n_steps: int, **config) -> int:
    """Native and ``SyncVectorEnv`` (3 sub-envs, ``mode``) give the same outputs step for step; returns the endings."""
    native = gym.make_vec(env_id, num_envs=3, autoreset_mode=mode, **config)
    sync = gym.make_vec(env_id, num_envs=3, vectorization_mode="sync", vector_kwargs={"autoreset_mode": mode}, **config)
    assert native.metadata["autoreset_mode"] == sync.metadata["autoreset_mode"] == mode
    native_outputs, sync_outputs = native.reset(seed=8), sync.reset(seed=8)
    rng, endings = np.random.default_rng(8), 0
    for step in range(n_steps + 1):
        for native_item, sync_item in zip(native_outputs[:-1], sync_outputs[:-1]):
            np.testing.assert_allclose(native_item, sync_item, rtol=0, atol=TOLERANCE, err_msg=f"step {step}")
        _assert_infos_match(native_outputs[-1], sync_outputs[-1], f"step {step}")
        if step < n_steps:
            actions = some_actions(rng, native_outputs[-1])
            native_outputs, sync_outputs = native.step(actions), sync.step(actions)
            endings += int(np.sum(native_outputs[2] | native_outputs[3]))
    native.close()
    sync.close()
    return endings


def _trajectory(env: gym.vector.VectorEnv, seed, n_steps: int = 25) -> list:
    steps = [env.reset(seed=seed)]
    rng = np.random.default_rng(1)
    for _ in range(n_steps):
        steps.append(env.step(some_actions(rng, steps[-1][-1])))
    return without_wall_clock(steps)


def check_seeding(env_id: str, **config) -> None:
    """Same seed, same trajectory bit for bit; ``s`` equals the list ``s + i``; a None in a list keeps a generator."""
    env = gym.make_vec(env_id, num_envs=4, **config)
    first = _trajectory(env, 3)
    assert data_equivalence(first, _trajectory(env, 3), exact=True)
    assert data_equivalence(first, _trajectory(gym.make_vec(env_id, num_envs=4, **config), [3, 4, 5, 6]))
    assert not data_equivalence(first, _trajectory(env, 4))  # (a reset observation alone may not show the seed)
    observations, _ = env.reset(seed=[7, None, np.int64(2), 5])
    single = gym.make(env_id, **config)
    np.testing.assert_array_equal(observations[0], single.reset(seed=7)[0])
    np.testing.assert_array_equal(observations[2], single.reset(seed=2)[0])
    generator = env.unwrapped.np_randoms[1]
    env.reset(seed=[1, None, 1, 1])
    assert env.unwrapped.np_randoms[1] is generator  # a None seed continues the sub-env's generator


def check_vector_api(env_id: str, n_steps: int = 30, **config) -> None:
    """Spaces, dtypes and shapes of the outputs, ``_key`` masks, ``action_masks()``, ``render()`` with no mode."""
    env, single = gym.make_vec(env_id, num_envs=5, **config), gym.make(env_id, **config)
    n_actions = single.action_space.n
    assert env.single_observation_space == single.observation_space and env.single_action_space == single.action_space
    assert env.action_space == gym.spaces.MultiDiscrete([n_actions] * 5)
    observations, info = env.reset(seed=0)
    assert observations.dtype == np.float32 and observations in env.observation_space
    for _ in range(n_steps):
        assert info["action_mask"].shape == (5, n_actions) and info["action_mask"].dtype == np.int8
        masks = env.unwrapped.action_masks()
        some = info["action_mask"].any(axis=1)
        np.testing.assert_array_equal(masks[some], info["action_mask"][some].astype(bool))
        assert masks.dtype == bool and masks[~some].all()  # no valid action: every action is the no-op
        observations, rewards, terminated, truncated, info = env.step(env.action_space.sample())
        assert observations in env.observation_space
        assert rewards.shape == (5,) and rewards.dtype == np.float64
        assert terminated.dtype == truncated.dtype == bool and terminated.shape == truncated.shape == (5,)
        assert all(info[f"_{key}"].shape == (5,) and info[f"_{key}"].all() for key in info if key[0] != "_")
    with pytest.warns(UserWarning, match="without a render_mode"):
        assert env.render() is None
    env.close()
    assert env.closed


def check_render_draws_sub_env_0(env_id: str, mode: AutoresetMode, n_steps: int, horizon: int) -> None:
    """``render()`` of ``render_mode="rgb_array"`` is sub-env 0's single env's frame, through its autoresets."""
    size = {"render_size_px": 96, "horizon": horizon}
    vector = gym.make_vec(env_id, num_envs=3, render_mode="rgb_array", autoreset_mode=mode, **size)
    single = gym.make(env_id, render_mode="rgb_array", **size)
    _, info = vector.reset(seed=21)
    single.reset(seed=21)
    rng, resetting, endings = np.random.default_rng(0), False, 0
    for step in range(n_steps):
        frame = vector.render()
        assert frame.shape == (96, 96, 3)
        np.testing.assert_array_equal(frame, single.render(), err_msg=f"step {step}")
        actions = some_actions(rng, info)
        _, _, terminated, truncated, info = vector.step(actions)
        ended = bool(terminated[0] or truncated[0])
        if resetting:  # NEXT_STEP: this step reset sub-env 0
            single.reset()
        else:
            single.step(actions[0])
            if ended and mode == AutoresetMode.SAME_STEP:
                single.reset()
        resetting, endings = ended and mode == AutoresetMode.NEXT_STEP, endings + ended
    assert endings >= 1
    vector.close()


def check_episode_statistics(env_id: str, horizon: int, **config) -> None:
    """Gymnasium's vector wrappers read the infos: ``RecordEpisodeStatistics`` sums each sub-env's rewards."""
    env = DictInfoToList(RecordEpisodeStatistics(gym.make_vec(env_id, num_envs=3, horizon=horizon, **config)))
    _, infos = env.reset(seed=2)
    assert len(infos) == 3 and all(reward_terms_of(info) and not any(reward_terms_of(info).values()) for info in infos)
    returns, lengths, first_episodes, done = np.zeros(3), np.zeros(3, dtype=int), {}, np.zeros(3, dtype=bool)
    while not done.all():
        _, rewards, terminated, truncated, infos = env.step(np.zeros(3, dtype=int))
        returns, lengths = returns + np.where(done, 0.0, rewards), lengths + ~done
        for copy in np.flatnonzero((terminated | truncated) & ~done).tolist():
            first_episodes[copy] = infos[copy]["episode"]
        done |= terminated | truncated
    for copy, episode in first_episodes.items():
        assert abs(episode["r"] - returns[copy]) <= 1e-5 and episode["l"] == lengths[copy], f"sub-env {copy}"
    assert sorted(first_episodes) == [0, 1, 2]


def check_other_vectorizations(env_id: str, **config) -> None:
    """``vectorization_mode="sync"`` and ``"async"`` still give Gymnasium's vector envs, with the native numbers."""
    native = gym.make_vec(env_id, num_envs=2, **config)
    for mode, kind in [("sync", gym.vector.SyncVectorEnv), ("async", gym.vector.AsyncVectorEnv)]:
        env = gym.make_vec(env_id, num_envs=2, vectorization_mode=mode, **config)
        assert isinstance(env, kind)
        np.testing.assert_allclose(env.reset(seed=4)[0], native.reset(seed=4)[0], rtol=0, atol=TOLERANCE)
        env.close()


def check_step_before_reset_raises(env_id: str) -> None:
    env = gym.make_vec(env_id, num_envs=2)
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(2, dtype=int))
    with pytest.raises(RuntimeError, match="reset"):
        env.unwrapped.action_masks()


def bad_actions(n_actions: int) -> list[tuple]:
    """``(actions for 3 sub-envs, the error they raise)`` pairs for an action space ``Discrete(n_actions)``."""
    return [
        (np.zeros(4, dtype=int), r"shape \(3,\).*got int64 of shape \(4,\)"),
        (np.zeros((3, 1), dtype=int), r"shape \(3,\)"),
        (np.zeros(3), "integer array.*float64"),
        (np.zeros(3, dtype=bool), "integer array.*bool"),
        (
            np.array([0, 1, n_actions]),
            rf"action {n_actions} of sub-env 2 is not in the action space Discrete\({n_actions}\)",
        ),
        ([0, -1, 0], rf"action -1 of sub-env 1 .*in \[0, {n_actions - 1}\]"),
    ]


def check_bad_actions_raise_naming_the_sub_env(env_id: str) -> None:
    env = gym.make_vec(env_id, num_envs=3)
    env.reset(seed=0)
    for actions, match in bad_actions(env.single_action_space.n):
        with pytest.raises(ValueError, match=match):
            env.step(actions)


def check_masked_actions_follow_invalid_action(env_id: str) -> None:
    """A masked action raises naming its sub-env with ``invalid_action="raise"``, else it is that sub-env's no-op.

    The other sub-envs' valid actions are taken as given (their ``chosen_action``), in both modes alike.
    """
    envs = {mode: gym.make_vec(env_id, num_envs=4, invalid_action=mode) for mode in ("raise", "noop")}
    infos = {mode: env.reset(seed=1)[1] for mode, env in envs.items()}
    rng = np.random.default_rng(1)
    for _ in range(50):  # until some sub-env has both a valid and a masked action
        mask = infos["noop"]["action_mask"]
        mixed = np.flatnonzero(mask.any(axis=1) & ~mask.all(axis=1))
        if mixed.size:
            break
        valid = np.array([rng.choice(np.flatnonzero(row)) if row.any() else 0 for row in mask])
        infos = {mode: env.step(valid)[-1] for mode, env in envs.items()}
    else:
        pytest.fail("no sub-env had a masked action beside a valid one within 50 steps")
    copy = int(mixed[0])
    actions = np.array([np.flatnonzero(row)[-1] if row.any() else 0 for row in mask])
    actions[copy] = int(np.flatnonzero(mask[copy] == 0)[0])
    with pytest.raises(ValueError, match=f"action {actions[copy]} of sub-env {copy} is not valid now"):
        envs["raise"].step(actions)
    info = envs["noop"].step(actions)[-1]
    np.testing.assert_array_equal(info["invalid_action"], np.arange(4) == copy)
    np.testing.assert_array_equal(info["chosen_action"], np.where(np.arange(4) == copy, -1, actions))


BAD_RESET_ARGUMENTS = [
    ({"seed": [1, 2]}, r"None, an int >= 0 or a list of 3 such seeds \(one per sub-env\), got \[1, 2\]"),
    ({"seed": -1}, "int >= 0"),
    ({"seed": [0, np.int64(3), -2]}, "int >= 0"),
    ({"seed": 1.5}, "seed"),
    ({"seed": [1, True, 2]}, "seed"),
    ({"options": {"reset_mask": [True] * 3}}, "takes no options"),
]


def check_bad_reset_arguments_raise(env_id: str) -> None:
    env = gym.make_vec(env_id, num_envs=3)
    for arguments, match in BAD_RESET_ARGUMENTS:
        with pytest.raises(ValueError, match=match):
            env.reset(**arguments)


def check_bad_vector_arguments_raise(env_id: str) -> None:
    """``num_envs``, ``render_mode`` and ``autoreset_mode`` errors name the value (and the env class)."""
    owner = type(gym.make_vec(env_id, num_envs=1).unwrapped).__name__
    for arguments, match in [
        ({"num_envs": 0}, f"num_envs of {owner} must be an int >= 1, got 0"),
        ({"num_envs": 2.0}, "num_envs .* got 2.0"),
        ({"render_mode": "rgb"}, r"render_mode must be None or one of \['human', 'rgb_array'\], got 'rgb'"),
        ({"autoreset_mode": "sometimes"}, f"autoreset_mode of {owner} must be one of 'next_step', 'same_step'"),
    ]:
        with pytest.raises(ValueError, match=match):
            gym.make_vec(env_id, **{"num_envs": 2, **arguments})


def check_autoreset_disabled(env_id: str, horizon: int = 3, **config) -> None:
    """With ``autoreset_mode="disabled"`` sub-envs step on past their end (observing nothing) until ``reset()``."""
    env = gym.make_vec(env_id, num_envs=2, horizon=horizon, autoreset_mode="disabled", **config)
    env.reset(seed=0)
    for step in range(1, horizon + 3):
        _, _, _, truncated, info = env.step(np.zeros(2, dtype=int))
        assert truncated.all() == (step >= horizon)
        np.testing.assert_allclose(info["time_s"], step * env.unwrapped.config["time_step_s"])
    _, info = env.reset()
    np.testing.assert_array_equal(info["time_s"], 0.0)


def _recording(reserve, draws: list):
    """``NoiseStreams.reserve`` that records the draw copy 0 takes next (if it takes one)."""

    def recorded(*args):
        blocks, next_draw = reserve(*args)
        draws.append(blocks[0, next_draw[0]].copy())
        return blocks, next_draw

    return recorded


def check_filter_equals_filterpy(env_id, landmark_of, monkeypatch, seed: int, n_steps: int, **config):
    """Along a whole episode of ``gym.make(env_id)`` (written once: its ``vector`` copy), its EKF equals raw filterpy
    (``filterpy_reference``) fed the same prior (the env's estimate after its reset), odometry readings and
    measurements (x within 1e-12, P within 1e-10; the readings made by ``OdometrySensor.measure_with_noise`` from the
    world's executed controls, the measurements by ``RangeBearingSensor.measure_with_noise``, both with the env's
    noise draws), and each update's ``reward_terms["mutual_information"]`` is that update's MI.

    Args:
        env_id: the registered id.
        landmark_of: the landmark an action observes (-1: none).
        monkeypatch: pytest's fixture.
        seed, n_steps: the episode's seed and length (mostly valid actions, some blind).
        config: the env config (``mapping`` estimates the landmarks in the state).

    Returns:
        How many updates the episode had.
    """
    draws = []
    env = gym.make(env_id, horizon=n_steps, **config).unwrapped
    vector = env.vector
    odometry, robot = vector.env_scenario.odometry, vector.state  # the scenario's constants and state
    worlds, odometry_noise, measurement_noise = robot.worlds, robot.odometry_noise, robot.measurement_noise
    sensor, controls, odometry_draws = vector.sensor, [], []
    world_step = worlds.step  # the executed controls, and below the noise draws the odometry reads them with
    monkeypatch.setattr(worlds, "step", lambda *args: controls.append(world_step(*args)) or controls[-1])
    monkeypatch.setattr(odometry_noise, "reserve", _recording(odometry_noise.reserve, odometry_draws))
    # the measurement's standard normals: the sensor measures with them below
    monkeypatch.setattr(measurement_noise, "reserve", _recording(measurement_noise.reserve, draws))
    _, info = env.reset(seed=seed)
    ekf = filterpy_filter(*vector.estimate(0))  # the prior: the pose, then the mapped landmarks if any
    rng, dt, mapping = np.random.default_rng(seed), env.config["time_step_s"], config.get("mapping")
    n_observed = 0
    for _ in range(n_steps):
        valid = np.flatnonzero(info["action_mask"])
        blind = rng.random() < 0.2 or not valid.size
        action = int(rng.integers(env.action_space.n)) if blind else int(rng.choice(valid))
        prior_P, true_pose = ekf.P.copy(), info["true_pose"]
        info = env.step(action)[4]
        landmark = landmark_of(info["chosen_action"])
        if landmark >= 0:
            true_landmark = vector.scenario(0).landmarks[landmark]
            column = 3 + 2 * landmark
            predicted, H = range_bearing(ekf.x, 0, ekf.x[column : column + 2] if mapping else true_landmark,
                                         column if mapping else None)  # fmt: skip
            R = sensor.noise_covariance(predicted[None, 0])[0]
            measurement = sensor.measure_with_noise(true_pose[None], true_landmark[None], draws[-1][None])[0]
            filterpy_update(ekf, measurement, predicted, H, R, [1], 1)
            realized = reward_terms_of(info)["mutual_information"]
            assert realized == pytest.approx(mutual_information(prior_P, ekf.P), abs=1e-10)
            n_observed += 1
        reading = odometry.measure_with_noise(controls[-1][0, 0], odometry_draws[-1])
        filterpy_predict(ekf, [reading], [odometry.noise_covariance()], dt)
        x, P = vector.estimate(0)
        np.testing.assert_allclose(x, ekf.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(P, ekf.P, rtol=0, atol=1e-10)
    assert len(controls) == n_steps
    return n_observed
