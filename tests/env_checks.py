"""The shared checks of a single-agent infonav env, for any registered id: ``check_env(env_id)`` runs them all.

``tests/test_envs.py`` runs each check on every registered Gymnasium env (and LandmarkSelection's
variants); a new env gets them by being registered. What a check expects of an env comes from
its declared ``traits`` (``infonav_gym.envs.traits.EnvTraits``), never from its id. The env must
take the config keys ``horizon`` and ``invalid_action`` ("noop" or "raise").
"""

from __future__ import annotations

import math
import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest
from conftest import assert_identical
from gymnasium.utils.env_checker import check_env as gymnasium_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

from infonav_gym.envs.traits import COMMON_INFO_KEYS, POSE_INFO_KEYS, EnvTraits, traits_of
from infonav_gym.envs.vector_infos import reward_terms_of
from infonav_gym.registry import make_env

WALL_CLOCK_INFO_KEYS = {"icp_time_s"}  # measured computing times: the only info that may differ between runs
OUT_OF_SPACE_ACTIONS = [-1, "n", 2.5, "a", True, np.array([0, 1])]  # "n": the space size, resolved per env


def without_wall_clock(value):
    """``value`` (a transition, an info, nested) without the measured computing times (``WALL_CLOCK_INFO_KEYS``)."""
    if isinstance(value, dict):
        return {key: without_wall_clock(item) for key, item in value.items() if key not in WALL_CLOCK_INFO_KEYS}
    if isinstance(value, (list, tuple)):
        return type(value)(without_wall_clock(item) for item in value)
    return value


def assert_reproducible(a, b, where: str = "value") -> None:
    """``assert_identical`` on everything but the measured computing times (``WALL_CLOCK_INFO_KEYS``)."""
    assert_identical(without_wall_clock(a), without_wall_clock(b), where)


def make(env_id: str, kwargs: dict, **extra) -> gym.Env:
    return make_env(env_id, **{**kwargs, **extra})


def traits(env_id: str, kwargs: dict | None = None) -> EnvTraits:
    """The traits the env ``env_id`` declares."""
    env = make(env_id, kwargs or {})
    env.close()
    return traits_of(env)


def copy_env(env: gym.Env) -> gym.Env:
    """A deep copy of the bare env through pickle."""
    return pickle.loads(pickle.dumps(env.unwrapped))


def choose_action(rng: np.random.Generator, info: dict, n_actions: int) -> int:
    """A random valid action per ``info["action_mask"]`` (any action when none is valid)."""
    valid = np.flatnonzero(info["action_mask"])
    return int(rng.choice(valid)) if valid.size else int(rng.integers(n_actions))


def step_in_lockstep(env_a, env_b, info_a: dict, n_steps: int, action_seed: int) -> int:
    """Step both envs with the same random valid actions (from env_a's mask); assert identical transitions."""
    rng = np.random.default_rng(action_seed)
    n_actions = env_a.action_space.n
    for step in range(n_steps):
        action = choose_action(rng, info_a, n_actions)
        transition_a = env_a.step(action)
        transition_b = env_b.step(action)
        assert_reproducible(
            transition_a, transition_b, f"step {step + 1} (action {action}): (obs, r, term, trunc, info)"
        )
        info_a = transition_a[4]
    return n_steps


def advance_to_mixed_mask(env, info: dict, max_steps: int = 200) -> dict:
    """Step with the last valid action until some action is valid and some is masked; return that step's info.

    (The last valid action spends the most bandwidth in SensorSelection, so its mask soon mixes.)
    """
    for _ in range(max_steps):
        mask = info["action_mask"]
        if mask.any() and not mask.all():
            return info
        valid = np.flatnonzero(mask)
        info = env.step(int(valid[-1]) if valid.size else 0)[4]
    pytest.skip(f"no step with both valid and masked actions within {max_steps} steps")


def collect_warnings(function, *args, **kwargs) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        function(*args, **kwargs)
    return [f"{w.category.__name__}: {w.message}" for w in caught]


# ----------------------------------------------------------------------------- the checks


def check_gymnasium_checker(env_id: str, kwargs: dict) -> None:
    """Gymnasium's ``check_env`` passes without a warning."""
    caught = collect_warnings(gymnasium_check_env, make(env_id, kwargs).unwrapped)
    assert caught == [], "gymnasium check_env warned:\n" + "\n".join(caught)


def check_sb3_checker(env_id: str, kwargs: dict) -> None:
    """Stable-Baselines3's ``check_env`` passes without a warning."""
    caught = collect_warnings(sb3_check_env, make(env_id, kwargs).unwrapped, warn=True)
    assert caught == [], "stable-baselines3 check_env warned:\n" + "\n".join(caught)


def check_same_seed_same_trajectory(env_id: str, kwargs: dict) -> None:
    """Two envs reset with one seed and stepped alike agree bit for bit for 200 steps."""
    env_a, env_b = make(env_id, kwargs), make(env_id, kwargs)
    reset_a, reset_b = env_a.reset(seed=123), env_b.reset(seed=123)
    assert_reproducible(reset_a, reset_b, "reset (obs, info)")
    step_in_lockstep(env_a, env_b, reset_a[1], n_steps=200, action_seed=7)


def check_reset_replays_the_episode(env_id: str, kwargs: dict) -> None:
    """``reset(seed=s)`` replays the episode on the same env, an unseeded episode in between."""
    env = make(env_id, kwargs, horizon=100)
    rng = np.random.default_rng(11)
    episodes = []
    for _ in range(2):
        observation, info = env.reset(seed=42)
        transitions = [(observation, info)]
        actions_rng = np.random.default_rng(5)
        for _ in range(100):
            transition = env.step(choose_action(actions_rng, info, env.action_space.n))
            transitions.append(transition)
            info = transition[4]
        episodes.append(transitions)
        # An unseeded episode in between must not leak into the re-seeded one.
        env.reset()
        for _ in range(10):
            env.step(int(rng.integers(env.action_space.n)))
    assert_reproducible(episodes[0], episodes[1], "episode replayed after reset(seed=42)")


def check_returned_values_are_copies(env_id: str, kwargs: dict) -> None:
    """Scribbling over returned observations and infos does not change what the env does next."""
    env_a, env_b = make(env_id, kwargs, horizon=60), make(env_id, kwargs, horizon=60)
    observation, info = env_a.reset(seed=9)
    env_b.reset(seed=9)
    rng = np.random.default_rng(2)
    for step in range(60):
        action = choose_action(rng, info, env_a.action_space.n)
        # Scribble over everything mutable that env_a returned; env_b is left alone.
        observation[...] = 0
        for value in info.values():
            if isinstance(value, np.ndarray):
                value[...] = 1
            elif isinstance(value, dict):
                value.clear()
        observation, _, _, _, info = env_a.step(action)
        transition_b = env_b.step(action)
        assert_reproducible((observation, info), (transition_b[0], transition_b[4]), f"step {step + 1}")


def check_pickled_env_continues_identically(env_id: str, kwargs: dict) -> None:
    env = make(env_id, kwargs).unwrapped
    _, info = env.reset(seed=5)
    rng = np.random.default_rng(3)
    for _ in range(4):
        info = env.step(choose_action(rng, info, env.action_space.n))[4]
    clone = pickle.loads(pickle.dumps(env))
    assert clone is not env
    step_in_lockstep(env, clone, info, n_steps=20, action_seed=4)


def check_out_of_space_action_raises(env_id: str, mode: str, bad_action) -> None:
    """An action outside the space raises ``ValueError`` naming the space, and changes nothing."""
    env = make(env_id, {}, invalid_action=mode, horizon=30)
    _, info = env.reset(seed=1)
    info = advance_to_mixed_mask(env, info)
    if isinstance(bad_action, str) and bad_action == "n":
        bad_action = env.action_space.n
    clone = copy_env(env)
    with pytest.raises(ValueError, match="action space"):
        env.step(bad_action)
    step_in_lockstep(env.unwrapped, clone, info, n_steps=3, action_seed=0)


def check_masked_action_is_a_no_op(env_id: str, kwargs: dict) -> None:
    """A masked action: reward 0, every term 0, ``invalid_action``; all masked actions alike; no pose update."""
    env = make(env_id, kwargs).unwrapped
    _, info = env.reset(seed=2)
    info = advance_to_mixed_mask(env, info)
    masked = np.flatnonzero(info["action_mask"] == 0)
    valid = np.flatnonzero(info["action_mask"])
    other_masked, with_valid = copy_env(env), copy_env(env)
    transition = env.step(int(masked[0]))
    _, reward, _, _, after = transition
    assert type(reward) is float and reward == 0.0
    assert after["invalid_action"] is True
    assert after["chosen_action"] == -1
    assert all(term == 0.0 for term in reward_terms_of(after).values())
    assert_reproducible(transition, other_masked.step(int(masked[-1])), "masked no-op vs another masked no-op")
    if traits_of(env).estimates_pose:
        assert reward_terms_of(after)["mutual_information"] == 0.0
        # No update, only the prediction: uncertainty cannot shrink.
        assert after["state_entropy"] >= info["state_entropy"]
        assert after["pose_entropy"] >= info["pose_entropy"]
        # A valid observation does update: less uncertainty than after the no-op.
        informative = valid[info["action_information_gain"][valid] > 0]
        assert with_valid.step(int(informative[0]))[4]["state_entropy"] < after["state_entropy"]


def check_masked_action_raises_in_raise_mode(env_id: str, kwargs: dict) -> None:
    """With ``invalid_action="raise"`` a masked action raises ``ValueError`` and changes nothing."""
    env = make(env_id, kwargs, invalid_action="raise").unwrapped
    _, info = env.reset(seed=2)
    info = advance_to_mixed_mask(env, info)
    masked = int(np.flatnonzero(info["action_mask"] == 0)[0])
    valid = int(np.flatnonzero(info["action_mask"])[-1])
    clone = copy_env(env)
    with pytest.raises(ValueError, match="action_mask"):
        env.step(masked)
    transition = env.step(valid)
    assert transition[4]["invalid_action"] is False
    assert transition[4]["chosen_action"] == valid
    if traits_of(env).rewards_information_at_once and info["action_information_gain"][valid] > 0:
        assert transition[1] > 0.0
    assert_reproducible(transition, clone.step(valid), "step after the rejected action vs an env that never saw it")


def check_step_before_reset_raises(env_id: str) -> None:
    env = make(env_id, {}).unwrapped
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)


def _check_decision(info: dict, n: int, declared: EnvTraits, where: str) -> None:
    """The info keys and the mask / gain contract of one decision."""
    required = COMMON_INFO_KEYS | declared.info_keys | (POSE_INFO_KEYS if declared.estimates_pose else set())
    assert required <= info.keys(), f"{where}: missing {required - info.keys()}"
    mask, gain = info["action_mask"], info["action_information_gain"]
    assert mask.dtype == np.int8 and mask.shape == (n,), where
    assert set(np.unique(mask).tolist()) <= {0, 1}, where
    assert gain.dtype == np.float64 and gain.shape == (n,), where
    informative = mask == 1
    informative[list(declared.idle_actions)] = False
    if declared.valid_gain_may_be_zero:
        assert np.all(gain[informative] >= 0.0), f"{where}: gain of a valid action is negative: {gain} {mask}"
    else:
        assert np.all(gain[informative] > 0.0), f"{where}: gain of a valid action is not positive: {gain} {mask}"
    assert np.all(gain[~informative] == 0.0), f"{where}: gain of a masked or idle action is not 0: {gain} {mask}"
    assert type(info["time_s"]) is float and info["true_pose"].shape == (3,), where
    if declared.estimates_pose:
        for key in ("pose_entropy", "state_entropy", "position_error_m", "heading_error_rad"):
            assert type(info[key]) is float and math.isfinite(info[key]), f"{where}: info[{key!r}] = {info[key]!r}"
        assert info["position_error_m"] >= 0 and 0 <= info["heading_error_rad"] <= math.pi, where
        assert info["estimated_pose"].shape == (3,), where


def _check_transition(transition, action: int, valid: bool, step: int, horizon: int, declared: EnvTraits) -> None:
    """Reward, termination and the reward terms of one step."""
    where = f"step {step}"
    _, reward, terminated, truncated, info = transition
    assert type(reward) is float, f"{where}: reward is {type(reward).__name__}"
    if terminated:
        assert declared.may_terminate and truncated is False, where
    else:
        assert truncated is (step + 1 == horizon), where
    terms = reward_terms_of(info)
    assert reward == sum(terms.values()), f"{where}: the reward is not the sum of its terms in order"
    assert reward == pytest.approx(math.fsum(terms.values()), rel=1e-12, abs=1e-12), where
    if declared.reward_terms:
        assert tuple(terms) == declared.reward_terms, where
    assert info["invalid_action"] is (not valid), where
    assert info["chosen_action"] == (action if valid else -1), where
    assert type(info["chosen_action"]) is int, where
    if declared.reports_success and (terminated or truncated):
        assert type(info["success"]) is bool, where


def check_episode_contract(env_id: str, kwargs: dict) -> None:
    """A whole episode of mostly valid, sometimes random actions keeps the spaces, info and reward contract."""
    env = make(env_id, kwargs)
    declared = traits_of(env)
    n = env.action_space.n
    observation, info = env.reset(seed=8)
    assert all(term == 0.0 for term in reward_terms_of(info).values())  # every term, 0: the same keys as a step's
    assert not declared.reward_terms or tuple(reward_terms_of(info)) == declared.reward_terms
    assert info["chosen_action"] == -1 and info["invalid_action"] is False
    rng = np.random.default_rng(8)
    horizon = env.unwrapped.config["horizon"]
    previous_time = -math.inf
    for step in range(horizon + 1):
        where = f"step {step}"
        assert observation.dtype == np.float32, where
        assert env.observation_space.contains(observation), f"{where}: observation outside observation_space"
        _check_decision(info, n, declared, where)
        assert info["time_s"] > previous_time, where
        previous_time = info["time_s"]
        if step == horizon:
            break
        action = int(rng.integers(n)) if rng.random() < 0.1 else choose_action(rng, info, n)
        valid = bool(info["action_mask"][action])
        transition = env.step(action)
        _check_transition(transition, action, valid, step, horizon, declared)
        observation, _, terminated, _, info = transition
        if terminated:
            assert env.observation_space.contains(observation), f"{where}: final observation outside the space"
            break


def check_truncation_at_horizon(env_id: str, kwargs: dict) -> None:
    """With ``horizon=7`` an env that never terminates truncates exactly at step 7."""
    env = make(env_id, kwargs, horizon=7)
    for seed in (0, 1):
        _, info = env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        for step in range(1, 8):
            _, _, terminated, truncated, info = env.step(choose_action(rng, info, env.action_space.n))
            assert terminated is False, f"terminated at step {step}"
            assert truncated is (step == 7), f"truncated={truncated} at step {step} with horizon=7"


def check_expected_gain_is_realized(env_id: str, kwargs: dict) -> None:
    """(``estimates_pose``) every valid action's reported gain is the MI it then brings, at 5 decisions."""
    env = make(env_id, kwargs).unwrapped
    _, info = env.reset(seed=6)
    rng = np.random.default_rng(6)
    decisions = 0
    for _ in range(200):
        valid = np.flatnonzero(info["action_mask"])
        if valid.size:
            for action in valid:
                realized = reward_terms_of(copy_env(env).step(int(action))[4])["mutual_information"]
                expected = info["action_information_gain"][action]
                assert realized == pytest.approx(expected, rel=1e-9, abs=0), f"action {action}"
            decisions += 1
            if decisions == 5:
                break
        info = env.step(choose_action(rng, info, env.action_space.n))[4]
    assert decisions == 5


def check_env(env_id: str, kwargs: dict | None = None) -> None:
    """Every check above that the env's traits make applicable."""
    kwargs = kwargs or {}
    declared = traits(env_id, kwargs)
    check_gymnasium_checker(env_id, kwargs)
    check_sb3_checker(env_id, kwargs)
    check_same_seed_same_trajectory(env_id, kwargs)
    check_reset_replays_the_episode(env_id, kwargs)
    check_returned_values_are_copies(env_id, kwargs)
    check_pickled_env_continues_identically(env_id, kwargs)
    for mode in ("noop", "raise"):
        for bad_action in OUT_OF_SPACE_ACTIONS:
            check_out_of_space_action_raises(env_id, mode, bad_action)
    check_masked_action_is_a_no_op(env_id, kwargs)
    check_masked_action_raises_in_raise_mode(env_id, kwargs)
    check_step_before_reset_raises(env_id)
    check_episode_contract(env_id, kwargs)
    if not declared.may_terminate:
        check_truncation_at_horizon(env_id, kwargs)
    if declared.estimates_pose and declared.gain_known_before_measuring:
        check_expected_gain_is_realized(env_id, kwargs)
