"""Learning curves of ``infonav train``: ``curve.csv`` rows against the episodes played, ``curve.png``, Ctrl-C."""

import json
import math
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, VectorWrapper

pytest.importorskip("sb3_contrib")

import agents.ppo  # noqa: E402
from agents.learning_curve import (  # noqa: E402
    CURVE_CSV,
    CURVE_PNG,
    METRIC_KEY,
    CurveCallback,
    MetricVectorWrapper,
    append_row,
    drawn_curve,
    read_curve,
)
from agents.ppo import load_hyperparameters, train  # noqa: E402
from agents.team_vec_env import RobotSlots  # noqa: E402
from infonav_gym.envs.traits import main_metric_of  # noqa: E402
from infonav_gym.experiments import cli  # noqa: E402
from infonav_gym.registry import make_env, make_vector_env  # noqa: E402

LANDMARK_ID = "infonav/LandmarkSelection-v0"
HORIZON = 20  # short episodes: many end in every rollout
SMALL = {**load_hyperparameters(LANDMARK_ID), "n_steps": 64, "batch_size": 128, "n_epochs": 1}


class RewardRecorder(VectorWrapper):
    """Records each step's float64 rewards and which sub-envs ended: the reference the curve is checked against."""

    def __init__(self, env):
        super().__init__(env)
        self.rewards, self.ended = [], []

    def step(self, actions):
        observations, rewards, terminated, truncated, info = self.env.step(actions)
        self.rewards.append(np.array(rewards, dtype=np.float64))
        self.ended.append(np.logical_or(terminated, truncated))
        return observations, rewards, terminated, truncated, info


def reference_rows(recorder: RewardRecorder, n_envs: int, row_steps) -> list[tuple[float, int]]:
    """(mean return, episodes) of the episodes that ended in each window ending at ``row_steps`` (env steps)."""
    returns, windows = np.zeros(n_envs), {steps: [] for steps in row_steps}
    for vector_step, (rewards, ended) in enumerate(zip(recorder.rewards, recorder.ended, strict=True), start=1):
        returns += rewards
        for index in np.flatnonzero(ended):
            window = min(steps for steps in row_steps if steps >= vector_step * n_envs)
            windows[window].append(returns[index])
            returns[index] = 0.0
    return [(math.fsum(window) / len(window), len(window)) for window in windows.values()]


def small_run(output, timesteps: int, n_envs: int, **options) -> None:
    """``train`` on LandmarkSelection's short episodes with the small block, quietly, without checkpoints."""
    train(
        LANDMARK_ID,
        timesteps,
        n_envs=n_envs,
        output_dir=output,
        hyperparameters=SMALL,
        progress=False,
        checkpoints=0,
        env_kwargs={"horizon": HORIZON},
        **options,
    )


@pytest.fixture(scope="module")
def native_run(tmp_path_factory):
    """A 3072-step MaskablePPO run on 8 native copies, its env's rewards recorded (about 5 s)."""
    recorders, monitored = [], agents.ppo.monitored_vec_env

    def recorded(vector_env, seed, info_keywords=()):
        recorders.append(RewardRecorder(vector_env))
        return monitored(recorders[-1], seed, info_keywords)

    output = tmp_path_factory.mktemp("curve")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(agents.ppo, "monitored_vec_env", recorded)
        small_run(output, 3000, 8, curve_references={"greedy": 5.0})
    return output, recorders[0]


def test_each_row_holds_the_mean_return_and_count_of_the_episodes_that_ended_in_its_rollout(native_run):
    output, recorder = native_run
    name, rows = read_curve(output / CURVE_CSV)
    assert name == "cumulative_mi"  # LandmarkSelection's main metric
    assert rows[:, 0].tolist() == [512 * k for k in range(1, 7)]  # a row per rollout of 64 steps x 8 copies
    assert np.isfinite(rows).all()
    reference = reference_rows(recorder, 8, rows[:, 0].tolist())
    assert rows[:, 3].tolist() == [count for _, count in reference]
    # SB3's monitor adds the rewards in float32
    np.testing.assert_allclose(rows[:, 1], [mean for mean, _ in reference], rtol=1e-5)
    # the main metric, cumulative MI, sums the env's only reward term: the float64 return itself
    np.testing.assert_allclose(rows[:, 2], [mean for mean, _ in reference], rtol=1e-12)
    record = json.loads((output / "train.json").read_text())
    assert record["curve"] == str(output / CURVE_PNG)


def test_the_png_has_a_return_panel_and_a_metric_panel(native_run):
    image = pytest.importorskip("matplotlib.image").imread(native_run[0] / CURVE_PNG)
    assert image.shape[:2] == (600, 700)  # two panels; one alone is 350 px high


@pytest.mark.parametrize(
    "env_id, config",
    [
        (LANDMARK_ID, {"horizon": 12}),
        # random moves fail or reach the wide goal at different steps: episodes of different lengths, metric 0 or 1
        ("infonav/ActiveLocalization-v0", {"horizon": 40, "goal_radius_m": 25.0, "max_position_std_m": 0.3}),
        ("infonav/SensorSelection-v0", {"horizon": 6}),
        ("infonav/RangeRegistration-v0", {"horizon": 4}),
    ],
)
def test_the_vector_wrapper_gives_the_metric_of_the_single_env_played_with_the_same_actions(env_id, config):
    """Sub-env i after reset(seed=s) is the single env after reset(seed=s + i), episode after episode: the metric
    the wrapper reads from the batched infos equals the env's ``EpisodeMetric`` on the single env's own infos."""
    vector_env = MetricVectorWrapper(gym.make_vec(env_id, num_envs=3, autoreset_mode=AutoresetMode.SAME_STEP, **config))
    vector_env.reset(seed=7)
    plays, ends = [], {index: [] for index in range(3)}  # ends: (steps played, metric) of each episode
    generator = np.random.default_rng(0)
    while min(map(len, ends.values())) < 2:
        masks = vector_env.unwrapped.action_masks()
        plays.append(np.argmax(masks * generator.random(masks.shape), axis=1))  # a random valid action
        *_, info = vector_env.step(plays[-1])
        for index in np.flatnonzero(info.get("final_info", {}).get(f"_{METRIC_KEY}", ())):
            ends[index].append((len(plays), info["final_info"][METRIC_KEY][index]))
    for index, episodes in ends.items():
        env = gym.make(env_id, **config)
        env.reset(seed=7 + index)
        played = 0
        for steps, metric in episodes:
            infos = [env.step(actions[index])[-1] for actions in plays[played:steps]]
            assert metric == main_metric_of(env).compute(infos)
            env.reset()
            played = steps


def test_sync_copies_record_the_metric_of_each_episode_too(tmp_path):
    small_run(tmp_path, 256, 2, vectorization="sync")
    _, rows = read_curve(tmp_path / CURVE_CSV)
    assert rows[:, 0].tolist() == [128, 256] and rows[:, 3].tolist() == [6, 6]
    np.testing.assert_allclose(rows[:, 2], rows[:, 1], atol=1e-6)  # SB3's Monitor rounds returns to 6 decimals


def test_ctrl_c_keeps_the_rows_so_far_and_draws_them(tmp_path, monkeypatch):
    end_rollout = CurveCallback._on_rollout_end

    def end_rollout_then_press_ctrl_c_at_the_second(self):
        end_rollout(self)
        if self.num_timesteps == 256:
            raise KeyboardInterrupt

    monkeypatch.setattr(CurveCallback, "_on_rollout_end", end_rollout_then_press_ctrl_c_at_the_second)
    small_run(tmp_path, 2000, 2)
    record = json.loads((tmp_path / "train.json").read_text())
    assert record["interrupted"] and record["timesteps"] == 256
    assert read_curve(tmp_path / CURVE_CSV)[1][:, 0].tolist() == [128, 256]
    assert record["curve"] == str(tmp_path / CURVE_PNG) and (tmp_path / CURVE_PNG).is_file()


def test_without_matplotlib_the_csv_stays_and_one_line_says_what_the_png_needs(tmp_path, monkeypatch):
    path = tmp_path / CURVE_CSV
    path.write_text("steps,mean_return,cumulative_mi,episodes\n")
    append_row(path, 100, 1.5, 2.5, 4)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    line = drawn_curve(tmp_path, "title", None)
    assert line == "curve.csv written; curve.png needs matplotlib: pip install 'infonav-gym[render]'"
    assert not (tmp_path / CURVE_PNG).exists()
    assert read_curve(path)[1].tolist() == [[100, 1.5, 2.5, 4]]


def test_a_curve_without_the_metric_is_the_return_panel_alone(tmp_path):
    path = tmp_path / CURVE_CSV
    path.write_text("steps,mean_return,cumulative_mi,episodes\n")
    for steps in (500, 1000):
        append_row(path, steps, steps / 100, math.nan, 3)
    image = pytest.importorskip("matplotlib.image").imread(drawn_curve(tmp_path, "title", None))
    assert image.shape[:2] == (350, 700)


def test_the_references_are_the_leaderboards_greedy_and_planner_means_of_the_same_env_and_config(tmp_path, monkeypatch):
    cell = {"summary": {"mean": 0.5}}
    rows = [
        {"env_id": "a", "env_kwargs": {}, "cells": {"random": cell, "greedy": cell, "planner": None}},
        {"env_id": "b", "env_kwargs": {"k": 1}, "cells": {"greedy": cell, "planner": {"summary": {"mean": 0.9}}}},
    ]
    leaderboard = tmp_path / "leaderboard.json"
    leaderboard.write_text(json.dumps({"rows": rows}))
    monkeypatch.setattr(cli, "LEADERBOARD_JSON", leaderboard)
    assert cli._curve_references("a", {}) == {"greedy": 0.5}
    assert cli._curve_references("b", {"k": 1}) == {"greedy": 0.5, "planner": 0.9}
    assert cli._curve_references("b", {}) is None
    monkeypatch.setattr(cli, "LEADERBOARD_JSON", tmp_path / "missing.json")
    assert cli._curve_references("a", {}) is None


def test_a_team_curve_counts_each_robots_episodes_with_the_teams_metric(tmp_path):
    small = {"n_steps": 32, "batch_size": 32, "n_epochs": 1}
    train(
        "cooperative_localization_v0",
        128,  # one rollout: 32 steps x 4 robots
        n_envs=1,
        output_dir=tmp_path,
        hyperparameters=small,
        progress=False,
        checkpoints=0,
        env_kwargs={"max_cycles": 8},
    )
    name, rows = read_curve(tmp_path / CURVE_CSV)
    assert name == "cumulative_mi" and rows[:, 0].tolist() == [128]  # 32 steps of 4 robot slots
    assert rows[0, 3] == 4 * 4 and np.isfinite(rows[0, 1]) and np.isfinite(rows[0, 2])  # 4 episodes of 8 steps a robot
    image = pytest.importorskip("matplotlib.image").imread(tmp_path / CURVE_PNG)
    assert image.shape[:2] == (600, 700)  # the return and metric panels


@pytest.mark.parametrize(
    "env_id, config",
    [
        ("cooperative_localization_v0", {"max_cycles": 5, "team_reward": 1.0}),
        # a tight position bound: random teams get lost at different steps, or cover nothing in time
        ("cooperative_exploration_v0", {"max_cycles": 12, "max_position_std_m": 0.3}),
    ],
)
def test_robot_slots_give_each_slot_the_team_metric_of_the_parallel_env_played_with_the_same_actions(env_id, config):
    slots = RobotSlots(make_vector_env(env_id, 2, autoreset_mode="same_step", **config))
    slots.reset(seed=7)
    n_robots = slots.n_robots
    plays, ends = [], {copy: [] for copy in range(2)}  # ends: (steps played, metric) of each episode
    generator = np.random.default_rng(0)
    while min(map(len, ends.values())) < 2:
        masks = slots.action_masks()
        plays.append(np.argmax(masks * generator.random(masks.shape), axis=1).reshape(2, n_robots))
        *_, info = slots.step(plays[-1].ravel())
        ended = info.get("final_info", {}).get(f"_{METRIC_KEY}", np.zeros(2 * n_robots, dtype=bool))
        for copy in range(2):
            robots = slice(copy * n_robots, (copy + 1) * n_robots)
            assert ended[robots].all() or not ended[robots].any()
            if ended[robots].all():
                assert len(set(info["final_info"][METRIC_KEY][robots])) == 1
                ends[copy].append((len(plays), info["final_info"][METRIC_KEY][robots][0]))
    for copy, episodes in ends.items():
        env = make_env(env_id, **config)
        env.reset(seed=7 + copy)
        played = 0
        for steps, metric in episodes:
            agents = list(env.possible_agents)
            infos = [env.step(dict(zip(agents, actions[copy].tolist())))[-1] for actions in plays[played:steps]]
            assert metric == main_metric_of(env).compute(infos)
            env.reset()
            played = steps
