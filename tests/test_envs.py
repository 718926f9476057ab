"""Behavioural tests of every registered infonav environment.

Environments are discovered from ``infonav_gym.ENVIRONMENTS``, so a newly
registered env is covered automatically; LandmarkSelection is additionally run
in each scenario x mapping combination. Checks of the pose estimate apply to the
localization envs (``LOCALIZATION_IDS``).
"""

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import math  # noqa: E402
import multiprocessing  # noqa: E402
import pickle  # noqa: E402
import warnings  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from conftest import assert_identical  # noqa: E402
from gymnasium.utils.env_checker import check_env as gymnasium_check_env  # noqa: E402
from stable_baselines3.common.env_checker import check_env as sb3_check_env  # noqa: E402

import infonav_gym  # noqa: E402
from infonav_gym.envs.active_localization import N_PRIMITIVES, REWARD_TERMS  # noqa: E402

LANDMARK_ID = "infonav/LandmarkSelection-v0"
SENSOR_ID = "infonav/SensorSelection-v0"
REGISTRATION_ID = "infonav/RangeRegistration-v0"
ACTIVE_ID = "infonav/ActiveLocalization-v0"
LOCALIZATION_IDS = {LANDMARK_ID, ACTIVE_ID}  # envs whose reward holds the MI of a pose update
TERMINATING_IDS = {ACTIVE_ID}  # envs whose episodes may end before the horizon (goal reached or failed)
REWARDED_EVERY_STEP_IDS = {LANDMARK_ID, SENSOR_ID}  # a valid informative action earns a positive reward at once
WALL_CLOCK_INFO_KEYS = {"icp_time_s"}  # measured computing times: the only info that may differ between runs
ENV_IDS = sorted(infonav_gym.ENVIRONMENTS)
LANDMARK_VARIANTS = [{"scenario": s, "mapping": m} for s in ("field", "corridor") for m in (False, True)]
ENV_CASES = [(env_id, {}) for env_id in ENV_IDS] + [(LANDMARK_ID, kwargs) for kwargs in LANDMARK_VARIANTS]
COMMON_INFO_KEYS = {"action_mask", "action_information_gain", "reward_terms", "chosen_action", "invalid_action"}
COMMON_INFO_KEYS |= {"true_pose", "time_s"}
LOCALIZATION_INFO_KEYS = {"pose_entropy", "state_entropy", "position_error_m", "heading_error_rad", "estimated_pose"}
REQUIRED_INFO_KEYS = {
    LANDMARK_ID: COMMON_INFO_KEYS | LOCALIZATION_INFO_KEYS,
    ACTIVE_ID: COMMON_INFO_KEYS
    | LOCALIZATION_INFO_KEYS
    | {"goal", "goal_reached", "failed", "observations_left", "distance_to_goal_m", "position_std_m"},
    SENSOR_ID: COMMON_INFO_KEYS | {"sensor", "pan_rad", "image_entropy", "bandwidth_credit_bytes"},
    REGISTRATION_ID: COMMON_INFO_KEYS
    | {"registered", "error_before_m", "error_after_m", "icp_iterations", "icp_time_s", "n_control_points"},
}
ZERO_GAIN_ACTIONS = {SENSOR_ID: {0}, ACTIVE_ID: set(range(N_PRIMITIVES))}  # valid actions never informative
MAY_BE_UNINFORMATIVE_IDS = {REGISTRATION_ID}  # a valid patch may hold no usable control point (gain 0)
OUT_OF_SPACE_ACTIONS = [-1, "n", 2.5, "a", True, np.array([0, 1])]  # "n": the space size, resolved per env


def _without_wall_clock(value):
    if isinstance(value, dict):
        return {key: _without_wall_clock(item) for key, item in value.items() if key not in WALL_CLOCK_INFO_KEYS}
    if isinstance(value, (list, tuple)):
        return type(value)(_without_wall_clock(item) for item in value)
    return value


def assert_reproducible(a, b, where: str = "value") -> None:
    """``assert_identical`` on everything but the measured computing times (``WALL_CLOCK_INFO_KEYS``)."""
    assert_identical(_without_wall_clock(a), _without_wall_clock(b), where)


def _case_id(case) -> str:
    env_id, kwargs = case
    name = env_id.split("/")[-1]
    return name + ("" if not kwargs else "[" + ",".join(f"{k}={v}" for k, v in kwargs.items()) + "]")


cases = pytest.mark.parametrize("env_id, kwargs", ENV_CASES, ids=[_case_id(c) for c in ENV_CASES])
LOCALIZATION_CASES = [case for case in ENV_CASES if case[0] in LOCALIZATION_IDS]
localization_cases = pytest.mark.parametrize(
    "env_id, kwargs", LOCALIZATION_CASES, ids=[_case_id(c) for c in LOCALIZATION_CASES]
)
env_ids = pytest.mark.parametrize("env_id", ENV_IDS)
mappings = pytest.mark.parametrize("mapping", [False, True], ids=["known_map", "mapping"])


# ----------------------------------------------------------------------------- helpers


def make(env_id: str, kwargs: dict, **extra) -> gym.Env:
    return gym.make(env_id, **{**kwargs, **extra})


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


# ----------------------------------------------------------------------------- registry


@env_ids
def test_registry_entry_is_registered_with_gymnasium_and_register_envs_is_idempotent(env_id):
    assert env_id in gym.registry
    assert gym.spec(env_id).entry_point == infonav_gym.ENVIRONMENTS[env_id]
    before = dict(gym.registry)
    infonav_gym.register_envs()
    assert gym.registry[env_id] is before[env_id]
    assert gym.make(env_id).unwrapped.__class__.__name__ == infonav_gym.ENVIRONMENTS[env_id].rsplit(":", 1)[1]


# ----------------------------------------------------------------------------- 1. env checkers


@cases
def test_gymnasium_env_checker_passes_without_warnings(env_id, kwargs):
    env = make(env_id, kwargs)
    caught = collect_warnings(gymnasium_check_env, env.unwrapped)
    assert caught == [], "gymnasium check_env warned:\n" + "\n".join(caught)


@pytest.mark.render
@cases
def test_gymnasium_env_checker_render_check_passes_without_warnings(env_id, kwargs):
    env = make(env_id, kwargs, render_mode="rgb_array")
    caught = collect_warnings(gymnasium_check_env, env.unwrapped, skip_render_check=False)
    env.close()
    assert caught == [], "gymnasium check_env (render check) warned:\n" + "\n".join(caught)


@cases
def test_sb3_env_checker_passes_without_warnings(env_id, kwargs):
    env = make(env_id, kwargs)
    caught = collect_warnings(sb3_check_env, env.unwrapped, warn=True)
    assert caught == [], "stable-baselines3 check_env warned:\n" + "\n".join(caught)


# ----------------------------------------------------------------------------- 2. determinism


@cases
def test_same_seed_and_actions_give_bit_identical_trajectories(env_id, kwargs):
    env_a, env_b = make(env_id, kwargs), make(env_id, kwargs)
    reset_a, reset_b = env_a.reset(seed=123), env_b.reset(seed=123)
    assert_reproducible(reset_a, reset_b, "reset (obs, info)")
    step_in_lockstep(env_a, env_b, reset_a[1], n_steps=200, action_seed=7)


@cases
def test_reset_with_same_seed_replays_the_episode_on_the_same_env(env_id, kwargs):
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


@mappings
def test_different_seeds_give_different_first_observations_in_field(mapping):
    env = gym.make(LANDMARK_ID, scenario="field", mapping=mapping)
    first = env.reset(seed=0)[0]
    second = env.reset(seed=1)[0]
    assert not np.array_equal(first, second)
    assert np.array_equal(first, env.reset(seed=0)[0])


@cases
def test_mutating_returned_observations_and_infos_does_not_affect_the_env(env_id, kwargs):
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


# ----------------------------------------------------------------------------- 3. pickle


@cases
def test_pickled_env_continues_identically(env_id, kwargs):
    env = make(env_id, kwargs).unwrapped
    _, info = env.reset(seed=5)
    rng = np.random.default_rng(3)
    for _ in range(4):
        info = env.step(choose_action(rng, info, env.action_space.n))[4]
    clone = pickle.loads(pickle.dumps(env))
    assert clone is not env
    step_in_lockstep(env, clone, info, n_steps=20, action_seed=4)


# ----------------------------------------------------------------------------- 4. spawned process


@env_ids
def test_spawned_process_makes_env_via_module_prefix_and_reproduces_the_observation(spawned_reset, env_id):
    parent_observation, _ = gym.make(env_id).reset(seed=3)
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        imported_before, child_observation = pool.apply_async(spawned_reset, (3, env_id)).get(timeout=120)
    assert not imported_before, "the child imported infonav_gym before gym.make: the test would prove nothing"
    assert child_observation == parent_observation.tolist()
    assert np.array_equal(np.array(child_observation, dtype=np.float32), parent_observation)


# ----------------------------------------------------------------------------- 5. config validation


@env_ids
def test_unknown_config_key_raises_naming_it(env_id):
    with pytest.raises(ValueError, match="not_a_key"):
        gym.make(env_id, not_a_key=1)


@env_ids
def test_misspelled_config_key_suggests_the_closest_key(env_id):
    with pytest.raises(ValueError, match="(?i)did you mean 'horizon'"):
        gym.make(env_id, horizn=5)


@pytest.mark.parametrize(
    "env_id, key, value",
    [(env_id, "horizon", "long") for env_id in ENV_IDS]
    + [(env_id, "horizon", 5.0) for env_id in ENV_IDS]
    + [(env_id, "invalid_action", 1) for env_id in ENV_IDS]
    + [(LANDMARK_ID, "mapping", 1.5), (LANDMARK_ID, "mapping", 1), (LANDMARK_ID, "n_candidates", True)]
    + [(LANDMARK_ID, "scenario", 3), (LANDMARK_ID, "range_std_m", "0.1")]
    + [(SENSOR_ID, "image_information", 1), (SENSOR_ID, "ladar_rows", 32.0), (SENSOR_ID, "camera_noise_std", "2")],
)
def test_wrongly_typed_config_value_raises_naming_the_key(env_id, key, value):
    with pytest.raises(ValueError, match=f"'{key}'"):
        gym.make(env_id, **{key: value})


@pytest.mark.parametrize(
    "env_id, key, value, options",
    [(env_id, "invalid_action", "explode", ("noop", "raise")) for env_id in ENV_IDS]
    + [(LANDMARK_ID, "scenario", "moon", ("field", "corridor"))]
    + [(SENSOR_ID, "image_information", "bits", ("entropy", "negentropy"))],
)
def test_invalid_choice_raises_listing_the_valid_options(env_id, key, value, options):
    with pytest.raises(ValueError, match=f"'{key}'") as error:
        gym.make(env_id, **{key: value})
    for option in options:
        assert option in str(error.value)


@env_ids
@pytest.mark.parametrize("horizon", [0, -3])
def test_non_positive_horizon_raises(env_id, horizon):
    with pytest.raises(ValueError, match="'horizon'"):
        gym.make(env_id, horizon=horizon)


@env_ids
@pytest.mark.filterwarnings("ignore:.*render_mode='bogus'.*:UserWarning")  # gymnasium's own make() warning
def test_unknown_render_mode_raises(env_id):
    with pytest.raises(ValueError, match="render_mode"):
        gym.make(env_id, render_mode="bogus")


def test_numpy_bool_is_accepted_for_bool_config_keys():
    # config._typed_like intends to accept numpy booleans (it tests for a type named "bool_").
    env = gym.make(LANDMARK_ID, mapping=np.bool_(True))
    assert env.unwrapped.config["mapping"] is True


@env_ids
@pytest.mark.parametrize("size_px", [0, -5])
def test_unusable_render_size_is_rejected_when_the_env_is_made(env_id, size_px):
    with pytest.raises(ValueError, match="render_size_px"):
        gym.make(env_id, render_mode="rgb_array", render_size_px=size_px)


# ----------------------------------------------------------------------------- 6. invalid actions


@env_ids
@pytest.mark.parametrize("mode", ["noop", "raise"])
@pytest.mark.parametrize("bad_action", OUT_OF_SPACE_ACTIONS, ids=repr)
def test_out_of_space_action_raises_naming_the_action_space_and_loses_nothing(env_id, mode, bad_action):
    env = gym.make(env_id, invalid_action=mode, horizon=30)
    _, info = env.reset(seed=1)
    info = advance_to_mixed_mask(env, info)
    if isinstance(bad_action, str) and bad_action == "n":
        bad_action = env.action_space.n
    clone = copy_env(env)
    with pytest.raises(ValueError, match="action space"):
        env.step(bad_action)
    step_in_lockstep(env.unwrapped, clone, info, n_steps=3, action_seed=0)


@cases
def test_masked_action_is_a_no_op_with_zero_reward(env_id, kwargs):
    env = make(env_id, kwargs).unwrapped
    _, info = env.reset(seed=2)
    info = advance_to_mixed_mask(env, info)
    masked = np.flatnonzero(info["action_mask"] == 0)
    valid = np.flatnonzero(info["action_mask"])
    other_masked, with_valid = copy_env(env), copy_env(env)

    transition = env.step(int(masked[0]))
    _, reward, terminated, truncated, after = transition
    assert type(reward) is float and reward == 0.0
    assert after["invalid_action"] is True
    assert after["chosen_action"] == -1
    assert all(term == 0.0 for term in after["reward_terms"].values())
    # Every masked action is the same no-op.
    assert_reproducible(transition, other_masked.step(int(masked[-1])), "masked no-op vs another masked no-op")
    if env_id in LOCALIZATION_IDS:
        if env_id == LANDMARK_ID:
            assert after["reward_terms"] == {"mutual_information": 0.0}
        else:
            assert after["reward_terms"]["mutual_information"] == 0.0
        # No update, only the prediction: uncertainty cannot shrink.
        assert after["state_entropy"] >= info["state_entropy"]
        assert after["pose_entropy"] >= info["pose_entropy"]
        # A valid observation does update: less uncertainty than after the no-op.
        informative = valid[info["action_information_gain"][valid] > 0]
        assert with_valid.step(int(informative[0]))[4]["state_entropy"] < after["state_entropy"]
    elif env_id == SENSOR_ID:
        # Nothing acquired, no bandwidth spent: the same as waiting.
        assert after["sensor"] == "none" and after["bandwidth_credit_bytes"] >= info["bandwidth_credit_bytes"]
        assert np.array_equal(transition[0], with_valid.step(0)[0])
    else:
        # No patch picked, no registration: only the horizon fraction moves on.
        assert after["registered"] is False and np.array_equal(after["action_mask"], info["action_mask"])
        picked = with_valid.step(int(valid[0]))
        assert picked[4]["action_mask"][valid[0]] == 0 or picked[4]["registered"]


@cases
def test_masked_action_raises_in_raise_mode_and_loses_nothing(env_id, kwargs):
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
    if env_id in REWARDED_EVERY_STEP_IDS:
        assert transition[1] > 0.0
    assert_reproducible(transition, clone.step(valid), "step after the rejected action vs an env that never saw it")


@env_ids
def test_step_before_reset_raises_runtime_error(env_id):
    env = gym.make(env_id).unwrapped
    with pytest.raises(RuntimeError, match="reset"):
        env.step(0)


# ----------------------------------------------------------------------------- 7. spaces / info contract


@cases
def test_observations_rewards_and_infos_follow_the_contract_for_a_whole_episode(env_id, kwargs):
    env = make(env_id, kwargs)
    n = env.action_space.n
    observation, info = env.reset(seed=8)
    assert info["reward_terms"] == {} and info["chosen_action"] == -1 and info["invalid_action"] is False
    rng = np.random.default_rng(8)
    horizon = env.unwrapped.config["horizon"]
    previous_time = -math.inf
    for step in range(horizon + 1):
        where = f"step {step}"
        assert observation.dtype == np.float32, where
        assert env.observation_space.contains(observation), f"{where}: observation outside observation_space"
        required = REQUIRED_INFO_KEYS[env_id]
        assert required <= info.keys(), f"{where}: missing {required - info.keys()}"
        mask, gain = info["action_mask"], info["action_information_gain"]
        assert mask.dtype == np.int8 and mask.shape == (n,), where
        assert set(np.unique(mask).tolist()) <= {0, 1}, where
        assert gain.dtype == np.float64 and gain.shape == (n,), where
        assert np.all(gain[mask == 0] == 0.0), f"{where}: gain of a masked action is not 0: {gain} {mask}"
        informative = mask == 1
        informative[list(ZERO_GAIN_ACTIONS.get(env_id, ()))] = False
        if env_id in MAY_BE_UNINFORMATIVE_IDS:
            assert np.all(gain[informative] >= 0.0), f"{where}: gain of a valid action is negative: {gain} {mask}"
        else:
            assert np.all(gain[informative] > 0.0), f"{where}: gain of a valid action is not positive: {gain} {mask}"
        assert np.all(gain[~informative] == 0.0), f"{where}: gain of a masked or idle action is not 0: {gain} {mask}"
        assert type(info["time_s"]) is float and info["true_pose"].shape == (3,), where
        if env_id in LOCALIZATION_IDS:
            for key in ("pose_entropy", "state_entropy", "position_error_m", "heading_error_rad"):
                assert type(info[key]) is float and math.isfinite(info[key]), f"{where}: info[{key!r}] = {info[key]!r}"
            assert info["position_error_m"] >= 0 and 0 <= info["heading_error_rad"] <= math.pi, where
            assert info["estimated_pose"].shape == (3,), where
        assert info["time_s"] > previous_time, where
        previous_time = info["time_s"]
        if step == horizon:
            break
        action = int(rng.integers(n)) if rng.random() < 0.1 else choose_action(rng, info, n)
        valid = bool(mask[action])
        observation, reward, terminated, truncated, info = env.step(action)
        assert type(reward) is float, f"{where}: reward is {type(reward).__name__}"
        if terminated and env_id in TERMINATING_IDS:
            assert truncated is False and info["goal_reached"] is not info["failed"], where
        else:
            assert terminated is False and truncated is (step + 1 == horizon), where
        if env_id == ACTIVE_ID:  # six terms: base.step adds them in order, which may differ from fsum in the last bit
            assert reward == sum(info["reward_terms"].values()), where
            assert reward == pytest.approx(math.fsum(info["reward_terms"].values()), rel=1e-12, abs=1e-12), where
        else:
            assert reward == math.fsum(info["reward_terms"].values()), where
        if env_id == LANDMARK_ID:
            assert info["reward_terms"].keys() == {"mutual_information"}, where
            assert reward == info["reward_terms"]["mutual_information"], where
        elif env_id == ACTIVE_ID:
            assert tuple(info["reward_terms"]) == REWARD_TERMS, where
        assert info["invalid_action"] is (not valid), where
        assert info["chosen_action"] == (action if valid else -1), where
        assert type(info["chosen_action"]) is int, where
        if terminated:
            assert env.observation_space.contains(observation), f"{where}: final observation outside the space"
            break


@cases
def test_episode_truncates_exactly_at_horizon_and_never_terminates(env_id, kwargs):
    env = make(env_id, kwargs, horizon=7)
    for seed in (0, 1):
        _, info = env.reset(seed=seed)
        rng = np.random.default_rng(seed)
        for step in range(1, 8):
            _, _, terminated, truncated, info = env.step(choose_action(rng, info, env.action_space.n))
            assert terminated is False, f"terminated at step {step}"
            assert truncated is (step == 7), f"truncated={truncated} at step {step} with horizon=7"


# ----------------------------------------------------------------------------- 8. exact information gain


@mappings
def test_reward_equals_the_gain_reported_before_acting_for_50_consecutive_steps(mapping):
    env = gym.make(LANDMARK_ID, scenario="field", mapping=mapping)
    _, info = env.reset(seed=4)
    rng = np.random.default_rng(4)
    while not info["action_mask"].any():  # start at the first decision with a choice
        info = env.step(0)[4]
    checked = 0
    for step in range(50):
        gains = info["action_information_gain"].copy()
        action = choose_action(rng, info, env.action_space.n)
        _, reward, _, _, info = env.step(action)
        if gains.any():
            assert reward == pytest.approx(gains[action], rel=1e-9, abs=0), f"step {step}, action {action}"
            checked += 1
        else:
            assert reward == 0.0
    assert checked >= 25, f"only {checked} of 50 steps had a valid action"


@localization_cases
def test_every_valid_actions_gain_equals_its_realized_reward(env_id, kwargs):
    env = make(env_id, kwargs).unwrapped
    _, info = env.reset(seed=6)
    rng = np.random.default_rng(6)
    decisions = 0
    for _ in range(200):
        valid = np.flatnonzero(info["action_mask"])
        if valid.size:
            for action in valid:
                _, reward, _, _, after = copy_env(env).step(int(action))
                realized = reward if env_id == LANDMARK_ID else after["reward_terms"]["mutual_information"]
                expected = info["action_information_gain"][action]
                assert realized == pytest.approx(expected, rel=1e-9, abs=0), f"action {action}"
            decisions += 1
            if decisions == 5:
                break
        info = env.step(choose_action(rng, info, env.action_space.n))[4]
    assert decisions == 5


# ----------------------------------------------------------------------------- 9. rendering


@pytest.mark.render
@cases
def test_rgb_array_render_returns_uint8_frames_that_change_over_time(env_id, kwargs):
    env = make(env_id, kwargs, render_mode="rgb_array", horizon=60)
    _, info = env.reset(seed=0)
    first = env.render()
    assert isinstance(first, np.ndarray) and first.dtype == np.uint8
    assert first.ndim == 3 and first.shape[2] == 3 and min(first.shape[:2]) > 0
    assert len(np.unique(first.reshape(-1, 3), axis=0)) > 2, "the frame is (almost) blank"
    rng = np.random.default_rng(0)
    for _ in range(60):
        info = env.step(choose_action(rng, info, env.action_space.n))[4]
    last = env.render()
    assert last.shape == first.shape and last.dtype == np.uint8
    assert not np.array_equal(first, last), "frames 60 steps apart are identical"
    env.close()
    env.close()


@pytest.mark.render
@env_ids
def test_rgb_array_frame_longer_side_is_render_size_px(env_id):
    env = gym.make(env_id, render_mode="rgb_array", render_size_px=240)
    env.reset(seed=0)
    assert max(env.render().shape[:2]) == 240
    env.close()


@pytest.mark.render
@env_ids
def test_human_render_with_dummy_driver_returns_none_and_close_is_idempotent(env_id):
    assert os.environ["SDL_VIDEODRIVER"] == "dummy"
    env = gym.make(env_id, render_mode="human", horizon=3)
    _, info = env.reset(seed=0)
    for _ in range(2):
        info = env.step(choose_action(np.random.default_rng(0), info, env.action_space.n))[4]
    assert env.render() is None
    env.close()
    env.close()


@env_ids
def test_render_without_render_mode_warns_and_returns_none(env_id):
    env = gym.make(env_id)
    env.reset(seed=0)
    with pytest.warns(UserWarning, match="render_mode"):
        assert env.render() is None
    env.close()


@pytest.mark.render
@env_ids
def test_env_that_has_rendered_pickles_and_the_copy_renders_the_same_frame(env_id):
    env = gym.make(env_id, render_mode="rgb_array").unwrapped
    _, info = env.reset(seed=1)
    for _ in range(10):
        info = env.step(choose_action(np.random.default_rng(1), info, env.action_space.n))[4]
    frame = env.render()
    clone = pickle.loads(pickle.dumps(env))
    assert np.array_equal(clone.render(), frame)
    env.close()
    clone.close()
