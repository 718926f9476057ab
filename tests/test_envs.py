"""Behavioural tests of every registered single-agent infonav environment.

Environments are discovered from the registry (``infonav_gym.registry``), so a newly
registered env is covered automatically; the checks live in ``env_checks.py`` (a test can run
them all on its own env with ``env_checks.check_env``) and adapt to each env's declared
``traits``. LandmarkSelection is additionally run in each scenario x mapping combination.
"""

import os

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import multiprocessing  # noqa: E402
import pickle  # noqa: E402

import env_checks  # noqa: E402
import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from env_checks import OUT_OF_SPACE_ACTIONS, choose_action, collect_warnings, copy_env, make  # noqa: E402
from gymnasium.utils.env_checker import check_env as gymnasium_check_env  # noqa: E402

import infonav_gym  # noqa: E402, F401  (registers the envs)
from infonav_gym.registry import GYMNASIUM, registered_envs  # noqa: E402

LANDMARK_ID = "infonav/LandmarkSelection-v0"
SENSOR_ID = "infonav/SensorSelection-v0"
REGISTRATION_ID = "infonav/RangeRegistration-v0"
ENV_IDS = [entry.id for entry in registered_envs(GYMNASIUM)]
LANDMARK_VARIANTS = [{"scenario": s, "mapping": m} for s in ("field", "corridor") for m in (False, True)]
ENV_CASES = [(env_id, {}) for env_id in ENV_IDS] + [(LANDMARK_ID, kwargs) for kwargs in LANDMARK_VARIANTS]


def _case_id(case) -> str:
    env_id, kwargs = case
    name = env_id.split("/")[-1]
    return name + ("" if not kwargs else "[" + ",".join(f"{k}={v}" for k, v in kwargs.items()) + "]")


def _cases_where(keep) -> pytest.MarkDecorator:
    """The env cases whose declared traits meet ``keep(traits)``, as a parametrization."""
    chosen = [case for case in ENV_CASES if keep(env_checks.traits(*case))]
    return pytest.mark.parametrize("env_id, kwargs", chosen, ids=[_case_id(c) for c in chosen])


cases = _cases_where(lambda traits: True)
localization_cases = _cases_where(lambda traits: traits.estimates_pose)
exact_gain_cases = _cases_where(lambda traits: traits.estimates_pose and traits.gain_known_before_measuring)
never_terminating_cases = _cases_where(lambda traits: not traits.may_terminate)
env_ids = pytest.mark.parametrize("env_id", ENV_IDS)
mappings = pytest.mark.parametrize("mapping", [False, True], ids=["known_map", "mapping"])


# ----------------------------------------------------------------------------- 1. env checkers


@cases
def test_gymnasium_env_checker_passes_without_warnings(env_id, kwargs):
    env_checks.check_gymnasium_checker(env_id, kwargs)


@pytest.mark.render
@cases
def test_gymnasium_env_checker_render_check_passes_without_warnings(env_id, kwargs):
    env = make(env_id, kwargs, render_mode="rgb_array")
    caught = collect_warnings(gymnasium_check_env, env.unwrapped, skip_render_check=False)
    env.close()
    assert caught == [], "gymnasium check_env (render check) warned:\n" + "\n".join(caught)


@cases
def test_sb3_env_checker_passes_without_warnings(env_id, kwargs):
    env_checks.check_sb3_checker(env_id, kwargs)


# ----------------------------------------------------------------------------- 2. determinism


@cases
def test_same_seed_and_actions_give_bit_identical_trajectories(env_id, kwargs):
    env_checks.check_same_seed_same_trajectory(env_id, kwargs)


@cases
def test_reset_with_same_seed_replays_the_episode_on_the_same_env(env_id, kwargs):
    env_checks.check_reset_replays_the_episode(env_id, kwargs)


@mappings
def test_different_seeds_give_different_first_observations_in_field(mapping):
    env = gym.make(LANDMARK_ID, scenario="field", mapping=mapping)
    first = env.reset(seed=0)[0]
    second = env.reset(seed=1)[0]
    assert not np.array_equal(first, second)
    assert np.array_equal(first, env.reset(seed=0)[0])


@cases
def test_mutating_returned_observations_and_infos_does_not_affect_the_env(env_id, kwargs):
    env_checks.check_returned_values_are_copies(env_id, kwargs)


# ----------------------------------------------------------------------------- 3. pickle


@cases
def test_pickled_env_continues_identically(env_id, kwargs):
    env_checks.check_pickled_env_continues_identically(env_id, kwargs)


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
    env_checks.check_out_of_space_action_raises(env_id, mode, bad_action)


@cases
def test_masked_action_is_a_no_op_with_zero_reward(env_id, kwargs):
    env_checks.check_masked_action_is_a_no_op(env_id, kwargs)


def _after_a_masked_action(env_id: str) -> tuple[dict, tuple, gym.Env]:
    """The info before, the transition of a masked action, and a copy of the env from before it."""
    env = make(env_id, {}).unwrapped
    _, info = env.reset(seed=2)
    info = env_checks.advance_to_mixed_mask(env, info)
    untouched = copy_env(env)
    return info, env.step(int(np.flatnonzero(info["action_mask"] == 0)[0])), untouched


def test_masked_sensor_selection_acquires_nothing_and_spends_no_bandwidth():
    info, transition, untouched = _after_a_masked_action(SENSOR_ID)
    after = transition[4]
    assert after["sensor"] == -1 and after["bandwidth_credit_bytes"] >= info["bandwidth_credit_bytes"]
    assert np.array_equal(transition[0], untouched.step(0)[0]), "a masked action is the same as waiting"


def test_masked_range_registration_picks_no_patch():
    info, transition, untouched = _after_a_masked_action(REGISTRATION_ID)
    after = transition[4]
    assert after["registered"] is False and np.array_equal(after["action_mask"], info["action_mask"])
    valid = int(np.flatnonzero(info["action_mask"])[0])
    picked = untouched.step(valid)
    assert picked[4]["action_mask"][valid] == 0 or picked[4]["registered"]


@cases
def test_masked_action_raises_in_raise_mode_and_loses_nothing(env_id, kwargs):
    env_checks.check_masked_action_raises_in_raise_mode(env_id, kwargs)


@env_ids
def test_step_before_reset_raises_runtime_error(env_id):
    env_checks.check_step_before_reset_raises(env_id)


# ----------------------------------------------------------------------------- 7. spaces / info contract


@cases
def test_observations_rewards_and_infos_follow_the_contract_for_a_whole_episode(env_id, kwargs):
    env_checks.check_episode_contract(env_id, kwargs)


@never_terminating_cases
def test_episode_truncates_exactly_at_horizon_and_never_terminates(env_id, kwargs):
    env_checks.check_truncation_at_horizon(env_id, kwargs)


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


@exact_gain_cases
def test_every_valid_actions_gain_equals_its_realized_reward(env_id, kwargs):
    env_checks.check_expected_gain_is_realized(env_id, kwargs)


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
