"""The env registry, the envs' declarations, and a toy env that gets the whole harness by registering.

``BeaconEnv`` is defined and registered here only: ``infonav evaluate``, the shared env checks
(``env_checks.check_env``) and the benchmark's env timing run it without knowing its id.
"""

from __future__ import annotations

import json
import math
import pickle
import subprocess
import sys

import env_checks
import gymnasium as gym
import numpy as np
import pytest
from conftest import assert_identical, greedy_actions
from gymnasium import spaces
from pettingzoo import ParallelEnv
from scipy import stats

import infonav_gym
from infonav_gym.config import check_choice, merge_config
from infonav_gym.envs.base import discrete_action_index
from infonav_gym.envs.metrics import SUCCESS_RATE, EpisodeMetric, final_value, summed_reward_term
from infonav_gym.envs.traits import COMMON_INFO_KEYS, EnvTraits, has_planning_model
from infonav_gym.envs.vector_infos import reward_terms_of
from infonav_gym.experiments.benchmark import benchmarked_env_ids, env_step_figures
from infonav_gym.experiments.cli import main
from infonav_gym.experiments.episodes import make_agent
from infonav_gym.experiments.evaluation import evaluate
from infonav_gym.experiments.intervals import wilson_interval
from infonav_gym.registry import GYMNASIUM, PARALLEL, env_entry, make_env, register, registered_envs, unregister

TOY_ID = "toy/Beacon-v0"
TEAM_ID = "cooperative_localization_v0"


class BeaconEnv(gym.Env):
    """A robot on a line picks one of ``n_beacons`` range beacons to hear; a scalar Kalman filter tracks it.

    Beacon ``k`` has noise variance ``0.1 (k + 1)`` [m^2] and is heard with probability 0.6 at each
    step (``info["action_mask"]``). The reward is the MI of the update, ``0.5 ln(P_prior / P_post)``.
    """

    metadata = {"render_modes": []}
    episode_metrics = (
        EpisodeMetric("cumulative_mi", "cumulative MI [nats]", summed_reward_term("mutual_information")),
        EpisodeMetric("final_position_std_m", "final position std [m]", final_value("position_std_m")),
        SUCCESS_RATE,
    )
    traits = EnvTraits(
        reports_success=True,
        rewards_information_at_once=True,
        reward_terms=("mutual_information",),
        info_keys=frozenset({"position_std_m", "success"}),
    )
    PROCESS_VARIANCE = 0.01  # [m^2 per step]
    SUCCESS_STD_M = 0.2

    @classmethod
    def default_config(cls) -> dict:
        return {"horizon": 20, "invalid_action": "noop", "n_beacons": 4}

    def __init__(self, render_mode: str | None = None, **config):
        self.render_mode = render_mode
        self.config = merge_config(self.default_config(), config, type(self).__name__)
        check_choice(self.config, "invalid_action", ("noop", "raise"), type(self).__name__)
        n = self.config["n_beacons"]
        self.noise_variances = 0.1 * np.arange(1, n + 1)
        self.action_space = spaces.Discrete(n)
        low, high = np.array([-1e4, 0, 0], dtype=np.float32), np.array([1e4, 1e4, 1], dtype=np.float32)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self._steps = None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        self._steps, self._terms, self._chosen = 0, {"mutual_information": 0.0}, -1
        self._position = float(self.np_random.normal())
        self._variance = float(self.np_random.uniform(0.5, 1.5))
        self._estimate = self._position + float(self.np_random.normal(0.0, math.sqrt(self._variance)))
        self._decide()
        return self._observation(), self._info(invalid=False)

    def _decide(self) -> None:
        self._mask = (self.np_random.random(self.action_space.n) < 0.6).astype(np.int8)
        prior = self._variance + self.PROCESS_VARIANCE
        gains = 0.5 * np.log((prior + self.noise_variances) / self.noise_variances)
        self._gains = np.where(self._mask == 1, gains, 0.0)

    def step(self, action):
        if self._steps is None:
            raise RuntimeError("BeaconEnv: call reset() before step()")
        action = discrete_action_index(action, self.action_space)
        valid = bool(self._mask[action])
        if not valid and self.config["invalid_action"] == "raise":
            raise ValueError(f"action {action} is not valid now (action_mask {self._mask.tolist()})")
        self._position += float(self.np_random.normal(0.0, math.sqrt(self.PROCESS_VARIANCE)))
        self._variance += self.PROCESS_VARIANCE
        information = 0.0
        if valid:
            noise = self.noise_variances[action]
            measured = self._position + float(self.np_random.normal(0.0, math.sqrt(noise)))
            gain = self._variance / (self._variance + noise)
            self._estimate += gain * (measured - self._estimate)
            posterior = self._variance * noise / (self._variance + noise)
            information, self._variance = float(0.5 * math.log(self._variance / posterior)), float(posterior)
        self._terms, self._chosen = {"mutual_information": information}, action if valid else -1
        self._steps += 1
        self._decide()
        truncated = self._steps >= self.config["horizon"]
        return self._observation(), float(sum(self._terms.values())), False, truncated, self._info(not valid)

    def _observation(self) -> np.ndarray:
        progress = self._steps / self.config["horizon"]
        return np.array([np.clip(self._estimate, -1e4, 1e4), math.sqrt(self._variance), progress], dtype=np.float32)

    def _info(self, invalid: bool) -> dict:
        return {
            "action_mask": self._mask.copy(),
            "action_information_gain": self._gains.copy(),
            **{f"reward_{term}": value for term, value in self._terms.items()},
            "chosen_action": self._chosen,
            "invalid_action": invalid,
            "true_pose": np.array([self._position, 0.0, 0.0]),
            "time_s": float(self._steps),
            "position_std_m": math.sqrt(self._variance),
            "success": bool(math.sqrt(self._variance) < self.SUCCESS_STD_M),
        }


def run_cli(capsys, *argv) -> str:
    assert main(list(argv)) == 0
    return capsys.readouterr().out


@pytest.fixture
def toy():
    """``BeaconEnv`` registered as ``TOY_ID`` by its string entry point for the test, unregistered after it."""
    register(TOY_ID, f"{__name__}:BeaconEnv")
    yield TOY_ID
    unregister(TOY_ID)


# ----------------------------------------------------------------------------- the registry


def test_every_builtin_env_is_registered_once_and_register_envs_is_idempotent():
    ids = [entry.id for entry in registered_envs()]
    assert ids == [entry[0] for entry in infonav_gym.BUILTIN_ENVS] and TEAM_ID in ids
    gymnasium_entries = {env_id: gym.registry[env_id] for env_id in [e.id for e in registered_envs(GYMNASIUM)]}
    infonav_gym.register_envs()
    assert [entry.id for entry in registered_envs()] == ids
    for env_id, spec in gymnasium_entries.items():
        assert gym.registry[env_id] is spec and spec.entry_point == env_entry(env_id).entry_point
    assert [entry.id for entry in registered_envs(PARALLEL)] == [
        TEAM_ID,
        "cooperative_exploration_v0",
        "mrclam_cooperative_localization_v0",
    ]
    assert TEAM_ID not in gym.registry and "cooperative_exploration_v0" not in gym.registry


def test_importing_the_package_registers_without_importing_any_env_module():
    script = (
        "import sys, infonav_gym; "
        "print(sorted(m for m in sys.modules if m.startswith(('infonav_gym.envs', 'infonav_gym.multi', 'pettingzoo'))))"
    )
    loaded = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert loaded.strip() == "[]"


@pytest.mark.parametrize("entry", registered_envs(), ids=lambda entry: entry.id)
def test_each_registered_env_is_of_its_api_and_declares_metrics_and_traits(entry):
    env = make_env(entry.id)
    assert type(env.unwrapped) is entry.load()
    assert isinstance(env, gym.Env if entry.api == GYMNASIUM else ParallelEnv)
    metrics = env.unwrapped.episode_metrics
    assert metrics and all(isinstance(metric, EpisodeMetric) for metric in metrics)
    assert len({metric.name for metric in metrics}) == len(metrics), "metric names repeat"
    assert isinstance(env.unwrapped.traits, EnvTraits)
    env.close()


@pytest.mark.parametrize("entry", registered_envs(), ids=lambda entry: entry.id)
def test_the_planner_is_made_exactly_for_the_envs_that_offer_a_planning_model(entry):
    env = make_env(entry.id)
    robot = None if entry.api == GYMNASIUM else env.possible_agents[0]
    n_actions = env.action_space.n if robot is None else env.action_space(robot).n
    if has_planning_model(env):
        assert type(make_agent("planner", n_actions, env=env, agent=robot)).__name__ == "PlannerAgent"
    else:
        with pytest.raises(ValueError, match=f"agent 'planner' is not available for {entry.id}"):
            make_agent("planner", n_actions, env=env, agent=robot)
    env.close()


@pytest.mark.parametrize("entry", registered_envs(PARALLEL), ids=lambda entry: entry.id)
def test_a_parallel_envs_infos_hold_the_declared_keys_and_reward_terms(entry):
    env = make_env(entry.id)
    declared = env.traits
    _, infos = env.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(3):
        for info in infos.values():
            assert COMMON_INFO_KEYS | declared.info_keys <= info.keys()
        actions = {agent: int(rng.integers(env.action_space(agent).n)) for agent in env.agents}
        infos = env.step(actions)[4]
        assert all(tuple(reward_terms_of(info)) == declared.reward_terms for info in infos.values())
        assert all(info["action_information_gain"][list(declared.idle_actions)].max() == 0.0 for info in infos.values())


@pytest.mark.parametrize("entry", registered_envs(PARALLEL), ids=lambda entry: entry.id)
def test_a_pickled_parallel_env_continues_identically(entry):
    env = make_env(entry.id)
    _, infos = env.reset(seed=4)
    for _ in range(5):
        _, _, _, _, infos = env.step(greedy_actions(env, infos))
    twin = pickle.loads(pickle.dumps(env))
    actions = greedy_actions(env, infos)
    assert_identical(env.step(actions), twin.step(actions))


def test_make_env_builds_the_parallel_env_by_its_id_with_config():
    team = make_env(TEAM_ID, max_cycles=5, n_robots=3)
    assert isinstance(team, ParallelEnv) and team.possible_agents == ["robot_0", "robot_1", "robot_2"]
    assert team.config["max_cycles"] == 5


def test_an_unknown_id_is_a_value_error_listing_every_registered_id():
    with pytest.raises(ValueError, match="unknown env id 'infonav/Nowhere-v0'") as error:
        make_env("infonav/Nowhere-v0")
    for entry in registered_envs():
        assert entry.id in str(error.value)
    with pytest.raises(ValueError, match="unknown env id 'nowhere'"):
        env_entry("nowhere")


@pytest.mark.parametrize(
    "env_id, entry_point, api, message",
    [
        (TEAM_ID, "somewhere:Else", PARALLEL, "already registered"),
        ("toy/X-v0", "no_colon_here", GYMNASIUM, "must be 'module:attribute'"),
        ("toy/X-v0", "module:Env", "aec", "api of env 'toy/X-v0' must be one of gymnasium, pettingzoo_parallel"),
    ],
)
def test_a_bad_registration_is_refused_naming_what_is_wrong(env_id, entry_point, api, message):
    with pytest.raises(ValueError, match=message):
        register(env_id, entry_point, api)
    assert "toy/X-v0" not in gym.registry and env_entry(TEAM_ID).entry_point != "somewhere:Else"


def test_a_registered_env_is_made_by_gymnasium_and_by_the_registry_and_unregistered(toy):
    assert register(TOY_ID, f"{__name__}:BeaconEnv") == env_entry(TOY_ID)  # again: nothing happens
    assert type(gym.make(toy).unwrapped) is BeaconEnv and type(make_env(toy, horizon=3).unwrapped) is BeaconEnv
    unregister(toy)
    assert toy not in gym.registry and toy not in [entry.id for entry in registered_envs()]
    register(TOY_ID, f"{__name__}:BeaconEnv")  # for the fixture to unregister


# ----------------------------------------------------------------------------- the toy env gets the harness


def test_the_toy_env_passes_the_shared_env_checks(toy):
    env_checks.check_env(toy)


def test_infonav_evaluate_runs_the_toy_env_with_its_declared_metrics(toy, capsys):
    argv = ["evaluate", "--env", toy, "--agents", "random,greedy", "--episodes", "6", "--config", "horizon=12"]
    result = json.loads(run_cli(capsys, *argv, "--json"))
    assert result["metrics"] == {metric.name: metric.title for metric in BeaconEnv.episode_metrics}
    assert result["env_config"] == {"horizon": 12, "invalid_action": "noop", "n_beacons": 4}
    env = make_env(toy, horizon=12)
    for name, agent in result["agents"].items():
        for seed, episode in zip(result["seeds"], agent["episodes"]):
            infos, info = [], env.reset(seed=seed)[1]
            player = make_agent(name, env.action_space.n)
            player.reset(seed=seed)
            while not infos or not infos[-1]["truncated"]:
                transition = env.step(player.act(None, info))
                info = transition[4]
                infos.append({**info, "truncated": transition[3]})
            assert episode == {metric.name: metric.compute(infos) for metric in BeaconEnv.episode_metrics}
        successes = sum(episode["success_rate"] for episode in agent["episodes"])
        low, high = stats.binomtest(int(successes), 6).proportion_ci(method="wilson")
        assert agent["summary"]["success_rate"]["interval"] == "wilson"
        assert agent["summary"]["success_rate"]["ci95_low"] == pytest.approx(low, abs=1e-12)
        assert agent["summary"]["success_rate"]["ci95_high"] == pytest.approx(high, abs=1e-12)
    printed = run_cli(capsys, *argv)
    assert "env config: horizon=12, invalid_action='noop', n_beacons=4" in printed
    assert "| greedy |" in printed and "final position std [m]" in printed and "Wilson score" in printed


def test_the_module_prefix_imports_the_module_that_registers_the_env(toy, capsys):
    result = json.loads(run_cli(capsys, "evaluate", "--env", f"{__name__}:{toy}", "--episodes", "1", "--json"))
    assert result["env_id"] == f"{__name__}:{toy}" and set(result["metrics"]) == {
        "cumulative_mi",
        "final_position_std_m",
        "success_rate",
    }
    with pytest.raises(ValueError, match="env id 'no_such_module:toy/X-v0': module 'no_such_module' does not import"):
        make_env("no_such_module:toy/X-v0")


def test_the_planner_is_refused_for_an_env_without_a_planning_model(toy):
    with pytest.raises(ValueError, match="'planner' is not available for toy/Beacon-v0: it declares no planning model"):
        evaluate(toy, ["planner"], episodes=1, progress=False)
    with pytest.raises(ValueError, match="infonav/ActiveLocalization-v0"):
        make_agent("planner", 4, env=make_env(toy))


def test_the_benchmark_times_the_toy_env_against_cartpole(toy):
    assert toy in benchmarked_env_ids()
    figures = env_step_figures([toy], rounds=1, seconds_per_round=0.02, progress=False)
    assert figures["beacon_steps_per_s"] > 0 and figures["cartpole_steps_per_s"] > 0
    ratio = figures["beacon_steps_per_s"] / figures["cartpole_steps_per_s"]
    assert figures["beacon_vs_cartpole_ratio"] == pytest.approx(ratio)


# ----------------------------------------------------------------------------- Wilson intervals


@pytest.mark.parametrize("successes, trials", [(0, 1), (0, 5), (3, 5), (5, 5), (17, 20), (1, 100)])
def test_wilson_interval_is_the_closed_form_and_scipys_and_inside_0_1(successes, trials):
    z, rate = stats.norm.ppf(0.975), successes / trials
    center = (successes + z**2 / 2) / (trials + z**2)
    half_width = z * math.sqrt(trials * rate * (1 - rate) + z**2 / 4) / (trials + z**2)
    low, high = wilson_interval(successes, trials)
    assert low == pytest.approx(max(0.0, center - half_width), abs=1e-12)
    assert high == pytest.approx(min(1.0, center + half_width), abs=1e-12)
    scipy_interval = stats.binomtest(successes, trials).proportion_ci(confidence_level=0.95, method="wilson")
    assert (low, high) == pytest.approx((scipy_interval.low, scipy_interval.high), abs=1e-12)
    assert 0.0 <= low <= rate <= high <= 1.0


@pytest.mark.parametrize("successes, trials", [(-1, 5), (6, 5), (0, 0)])
def test_wilson_interval_refuses_impossible_counts(successes, trials):
    with pytest.raises(ValueError, match=f"got {successes} of {trials}"):
        wilson_interval(successes, trials)
