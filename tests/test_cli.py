"""The ``infonav`` command: demo, evaluate, benchmark, reproduce."""

import json
import math
import os

import numpy as np
import pytest
from scipy import stats

from infonav_gym.compiled import MIN_COPIES_PER_THREAD
from infonav_gym.experiments import benchmark, startup_timing
from infonav_gym.experiments.cli import _config_pair, main
from infonav_gym.experiments.distributed_timing import rllib_missing
from infonav_gym.experiments.intervals import ProportionSummary, Summary, wilson_interval
from infonav_gym.experiments.vector_timing import torchrl_missing

RLLIB_EXPLORATION = "rllib_exploration_1_runner_steps_per_s"
RLLIB_FIGURES = {
    "rllib_team_1_runner_steps_per_s": 300.0,
    "rllib_team_2_runners_steps_per_s": 450.0,
    "rllib_team_2_runners_vs_1_ratio": 1.5,
    RLLIB_EXPLORATION: 900.0,
}


def run_json(capsys, *argv) -> dict:
    assert main([*argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_demo_tells_the_fig2_story(capsys):
    demo = run_json(capsys, "demo", "--steps", "4")
    greedy, random = demo["runs"]["greedy"], demo["runs"]["random"]
    assert [record["choice"] for record in greedy] == [2, 2, 2, 2], "greedy observes landmark #3"
    for record in greedy:
        gains = record["information_contribution"]
        assert len(gains) == 4 and record["realized"] == pytest.approx(max(gains), rel=1e-9)
    assert sum(r["realized"] for r in greedy) > sum(r["realized"] for r in random)


def test_demo_prints_a_table_and_writes_the_plot(capsys, tmp_path):
    pytest.importorskip("matplotlib")
    assert main(["demo", "--steps", "2", "--plot", str(tmp_path / "fig2.png")]) == 0
    out = capsys.readouterr().out
    assert "ic #3" in out and "greedy agent" in out and "random agent" in out
    assert (tmp_path / "fig2.png").stat().st_size > 10_000


def test_evaluate_is_reproducible_and_uses_the_same_seeds_for_every_agent(capsys):
    argv = ["evaluate", "--episodes", "3", "--seed", "5", "--config", "horizon=30"]
    first, second = run_json(capsys, *argv), run_json(capsys, *argv)
    assert first == second
    assert first["seeds"] == [5, 6, 7] and first["env_kwargs"] == {"horizon": 30}
    assert set(first["agents"]) == {"random", "greedy"}
    for result in first["agents"].values():
        assert len(result["episodes"]) == 3
        mean = result["summary"]["cumulative_mi"]["mean"]
        assert mean == pytest.approx(np.mean([e["cumulative_mi"] for e in result["episodes"]]))


def test_evaluate_runs_the_team_env_with_team_metrics_reproducibly(capsys):
    argv = ["evaluate", "--env", "cooperative_localization_v0", "--episodes", "2", "--config", "max_cycles=20"]
    first, second = run_json(capsys, *argv), run_json(capsys, *argv)
    assert first == second and set(first["agents"]) == {"random", "greedy"}
    for result in first["agents"].values():
        assert all(episode["cumulative_mi"] > 0 and episode["pose_rmse_m"] > 0 for episode in result["episodes"])
    with pytest.raises(SystemExit) as error:
        main(["evaluate", "--env", "cooperative_localization_v0", "--agents", "greedy,oracle"])
    assert error.value.code == 2 and "unknown agent 'oracle'" in capsys.readouterr().err


def test_evaluate_prints_the_env_config_it_ran_defaults_included(capsys):
    argv = ["evaluate", "--env", "cooperative_localization_v0", "--episodes", "1", "--config", "max_cycles=5"]
    assert run_json(capsys, *argv)["env_config"]["team_reward"] == 0.0  # the default reward choice, visible
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "env config: max_cycles=5, " in printed and "team_reward=0.0" in printed
    assert "mean ± half-width of its 95% confidence interval (Student t)" in printed
    assert printed.splitlines()[0].endswith("seeds 0..0; reward set by team_reward=0.0 (default)")
    assert "± n/a" in printed and "nan" not in printed  # one episode: no interval
    assert main([*argv, "--config", "team_reward=1.0"]) == 0
    assert capsys.readouterr().out.splitlines()[0].endswith("; reward set by team_reward=1.0")


def test_evaluate_writes_markdown_csv_and_json_with_the_command(capsys, tmp_path):
    stem = tmp_path / "eval"
    main(["evaluate", "--episodes", "2", "--config", "horizon=10", "--output", str(stem)])
    table = capsys.readouterr().out
    assert "| greedy |" in table and "cumulative MI" in table
    markdown = (tmp_path / "eval.md").read_text()
    assert "infonav evaluate --episodes 2 --config horizon=10 --output" in markdown
    assert "env config: horizon=10, " in markdown and "95% confidence interval (Student t)" in markdown
    rows = (tmp_path / "eval.csv").read_text().strip().splitlines()
    assert rows[0] == "agent,seed,cumulative_mi,final_pose_entropy,pose_rmse_m" and len(rows) == 1 + 2 * 2
    assert json.loads((tmp_path / "eval.json").read_text())["command"].startswith("infonav evaluate")


def test_confidence_interval_is_students_t():
    values = [1.0, 2.5, 2.0, 4.0, 3.1]
    low, high = stats.t.interval(0.95, len(values) - 1, loc=np.mean(values), scale=stats.sem(values))
    summary = Summary.of(values)
    assert math.isclose(summary.mean - summary.ci95, low) and math.isclose(summary.mean + summary.ci95, high)
    assert math.isnan(Summary.of([1.0]).ci95)


def test_a_rate_is_summarized_by_its_wilson_interval_and_must_be_0_or_1():
    summary = ProportionSummary.of([1.0, 0.0, 1.0, 1.0])
    assert summary.mean == 0.75 and (summary.low, summary.high) == wilson_interval(3, 4)
    assert summary.as_dict() == {"mean": 0.75, "ci95_low": summary.low, "ci95_high": summary.high, "interval": "wilson"}
    with pytest.raises(ValueError, match=r"values 0 or 1 per episode, got \[1.0, 0.5\]"):
        ProportionSummary.of([1.0, 0.5])


@pytest.mark.parametrize(
    "argv, message",
    [
        (["evaluate", "--agents", "random,oracle", "--episodes", "1"], "unknown agent 'oracle'"),
        (["evaluate", "--config", "horizn=3", "--episodes", "1"], "Did you mean 'horizon'"),
        (["reproduce", "fig4"], "invalid choice: 'fig4' (choose from 'fig3', 'fig5', 'fig6')"),
    ],
)
def test_bad_arguments_exit_2_with_a_message(capsys, argv, message):
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err


def test_config_values_must_be_key_value_pairs(capsys):
    with pytest.raises(SystemExit):
        main(["evaluate", "--config", "no-equals-sign"])
    assert "KEY=VALUE" in capsys.readouterr().err


@pytest.mark.slow  # every benchmark figure, briefly
def test_benchmark_reports_every_goal(capsys, monkeypatch):
    # the start-up processes only import the suite here, for one env: compiling every kernel cold is the benchmark's
    monkeypatch.setattr(startup_timing, "FIRST_STEP_SCRIPT", "import infonav_gym")
    monkeypatch.setattr(benchmark, "startup_figures", lambda env_ids: startup_timing.startup_figures(env_ids[:1]))
    # RLlib's figures are sampled in tests/test_rllib.py, on the Ray it starts anyway: here they are given
    rllib, rllib_calls = RLLIB_FIGURES if rllib_missing() is None else {}, []
    monkeypatch.setattr(benchmark, "rllib_runner_figures", lambda *args: rllib_calls.append(args) or dict(rllib))
    monkeypatch.setattr(benchmark, "THREADED_COPIES", 2 * MIN_COPIES_PER_THREAD)  # two chunks, not 4096 copies
    monkeypatch.setattr(benchmark, "TORCHRL_COPIES", 4)  # not 256
    # the training rates are measured in tests/test_team_ppo.py and tests/test_rllib.py: here a quick run asks for few
    training_calls = []
    monkeypatch.setattr(
        benchmark, "training_figures", lambda *args: training_calls.append(args) or {"sb3_train_steps_per_s": 1.0}
    )
    result = run_json(capsys, "benchmark", "--rounds", "1", "--seconds", "0.01", "--vector-sizes", "1,4")
    assert training_calls == [(0, benchmark.QUICK_TRAINING_COPIES)]
    figures = result["figures"]
    threads_ratio = figures.get(f"landmark_selection_vector_{2 * MIN_COPIES_PER_THREAD}_threads_2_vs_1_ratio")
    assert (threads_ratio is None) == (os.cpu_count() < 2) and (threads_ratio is None or threads_ratio > 0)
    for env in ("landmark_selection", "cooperative_localization", "sensor_selection"):
        assert figures[f"{env}_steps_per_s"] > 0 and figures["cartpole_steps_per_s"] > 0
        ratio = figures[f"{env}_steps_per_s"] / figures["cartpole_steps_per_s"]
        assert figures[f"{env}_vs_cartpole_ratio"] == pytest.approx(ratio)
    vector_ratio = figures["sensor_selection_vector_4_steps_per_s"] / figures["cartpole_steps_per_s"]
    assert figures["sensor_selection_vector_4_vs_cartpole_ratio"] == pytest.approx(vector_ratio)
    assert result["goals_met"]["sensor_selection_vector_256_vs_cartpole_ratio"] is None  # N = 256 was not timed
    for sensor in ("ladar", "camera"):
        frame_ms, pymunk_ms = figures[f"{sensor}_frame_ms"], figures[f"pymunk_{sensor}_rays_ms"]
        assert frame_ms > 0 and pymunk_ms > 0
        assert figures[f"{sensor}_vs_pymunk_ratio"] == pytest.approx(frame_ms / pymunk_ms)
        assert result["goals_met"][f"{sensor}_frame_ms"] == (frame_ms <= result["goals"][f"{sensor}_frame_ms"])
    assert (
        set(result["goals_met"])
        == set(result["goals"])
        == {
            "landmark_selection_vs_cartpole_ratio",
            "cooperative_localization_vs_cartpole_ratio",
            "sensor_selection_vs_cartpole_ratio",
            "greedy_decision_us",
            "ladar_frame_ms",
            "camera_frame_ms",
            "icp_frame_pair_ms",
            "icp_vs_open3d_icp_scan_40k_time_ratio",
            "gicp_vs_small_gicp_scan_40k_time_ratio",
            "ppo_fps_ratio_vs_cartpole",
            "ppo_vector_fps_ratio_vs_cartpole",
            "landmark_selection_vector_256_vs_cartpole_ratio",
            "active_localization_vector_256_vs_cartpole_ratio",
            "sensor_selection_vector_256_vs_cartpole_ratio",
            "cooperative_localization_vector_256_vs_vmas_ratio",
            "cooperative_exploration_vector_256_vs_vmas_ratio",
            "range_registration_vector_256_vs_single_ratio",
            "evaluation_2_workers_time_ratio",
            "rllib_team_2_runners_vs_1_ratio",
            "rllib_exploration_1_runner_steps_per_s",
            "landmark_selection_vector_1024_kb_per_env",
            "active_localization_vector_1024_kb_per_env",
            "cooperative_localization_vector_1024_kb_per_env",
            "landmark_selection_vector_4096_threads_2_vs_1_ratio",
            "cold_start_s",
            "warm_start_s",
            "landmark_selection_vector_1024_vs_cartpole_ratio",
            "active_localization_vector_1024_vs_cartpole_ratio",
            "cooperative_localization_vector_1024_vs_vmas_ratio",
            "cooperative_exploration_vector_1024_vs_vmas_ratio",
            "sensor_selection_vector_256_vs_single_ratio",
            "range_registration_vector_64_vs_single_ratio",
            "cold_start_all_envs_s",
            "map_registration_step_vs_range_registration_registering_step_time_ratio",
            "cooperative_localization_torchrl_256_vs_native_ratio",
            "cooperative_exploration_torchrl_256_vs_native_ratio",
            "sb3_vs_rllib_train_steps_ratio",
            "sb3_vs_benchmarl_train_steps_ratio",
        }
    )
    assert result["goals_met"]["sb3_vs_rllib_train_steps_ratio"] is None  # the stand-in training figures have none
    for team in ("cooperative_localization", "cooperative_exploration"):
        name = f"{team}_torchrl_4"
        if torchrl_missing() is None:
            torchrl, native = figures[f"{name}_steps_per_s"], figures[f"{name}_native_steps_per_s"]
            assert torchrl > 0 and figures[f"{name}_vs_native_ratio"] == pytest.approx(torchrl / native)
        else:
            assert f"{name}_vs_native_ratio" not in figures and any("TorchRL" in note for note in result["notes"])
        assert result["goals_met"][f"{team}_torchrl_256_vs_native_ratio"] is None  # N = 256 was not timed
    for start in ("cold_start_s", "warm_start_s", "cold_start_all_envs_s"):
        assert figures[start] > 0 and result["goals_met"][start] == (figures[start] <= result["goals"][start])
    ppo_fps, cartpole_ppo_fps = figures["ppo_landmark_selection_fps"], figures["ppo_cartpole_fps"]
    assert ppo_fps > 0 and cartpole_ppo_fps > 0 and figures["ppo_timesteps_per_round"] <= 512
    assert figures["ppo_fps_ratio_vs_cartpole"] == pytest.approx(ppo_fps / cartpole_ppo_fps)  # one round: one ratio
    assert result["goals_met"]["ppo_fps_ratio_vs_cartpole"] == (figures["ppo_fps_ratio_vs_cartpole"] >= 0.5)
    vector_fps, cartpole_vector_fps = figures["ppo_landmark_selection_vector_fps"], figures["ppo_cartpole_vector_fps"]
    assert figures["ppo_vector_n_envs"] == 64 and figures["ppo_vector_timesteps_per_round"] == 1024  # 64 x 16 steps
    vector_ratio = figures["ppo_vector_fps_ratio_vs_cartpole"]
    assert vector_ratio == pytest.approx(vector_fps / cartpole_vector_fps)
    assert result["goals_met"]["ppo_vector_fps_ratio_vs_cartpole"] == (vector_ratio >= 0.85)
    assert figures["icp_frame_pair_ms"] > 0
    assert result["goals_met"]["icp_frame_pair_ms"] == (figures["icp_frame_pair_ms"] <= 20.0)
    for registration in ("icp", "gicp"):
        for pair in ("frame_pair", "scan_40k"):
            assert figures[f"{registration}_{pair}_rotation_error_deg"] < 0.5
            assert figures[f"{registration}_{pair}_translation_error_m"] < 0.05
    evaluation_ratio = figures["evaluation_2_workers_time_ratio"]
    assert figures["evaluation_episodes_per_agent"] == 2 and evaluation_ratio > 0
    assert result["goals_met"]["evaluation_2_workers_time_ratio"] == (evaluation_ratio <= 0.65)
    two_over_one = figures["evaluation_2_workers_s"] / figures["evaluation_1_worker_s"]
    assert evaluation_ratio == pytest.approx(two_over_one)  # one round: one ratio
    assert rllib_calls == [(0, 100)]  # the seed, and the quick run's 100 sampled steps per runner at least
    rllib_met = [result["goals_met"][name] for name in ("rllib_team_2_runners_vs_1_ratio", RLLIB_EXPLORATION)]
    if rllib:
        assert rllib.items() <= figures.items() and rllib_met == [True, False]  # 1.5 >= 1.5, 900 < 1000
    else:
        assert rllib_met == [None, None] and any("RLlib figures absent" in note for note in result["notes"])


def test_reproduce_fig3_writes_the_plot_and_the_json_it_prints(capsys, tmp_path):
    pytest.importorskip("matplotlib")
    result = run_json(capsys, "reproduce", "fig3", "--output-dir", str(tmp_path), "--seeds", "2")
    assert (tmp_path / "fig3.png").stat().st_size > 10_000
    written = json.loads((tmp_path / "fig3.json").read_text())
    assert written == result
    assert written["command"] == f"infonav reproduce fig3 --output-dir {tmp_path} --seeds 2 --json"
    assert written["files"] == [str(tmp_path / "fig3.png"), str(tmp_path / "fig3.json")]
    fig3, rmse = written["fig3"], written["outage_rmse"]
    assert fig3["seed"] == 0 and fig3["dgps_loss_s"] == 21.0 and len(fig3["steps"]) == 120
    assert {"time_s", "pose_std", "pose_std_after_update", "gps_available", "gains_nats", "chosen"} == set(
        fig3["steps"][0]
    )
    assert set(fig3["paths"]["greedy"]) == {"robot_0", "robot_1"} and fig3["corrections"]
    assert rmse["seeds"] == [0, 1] and [record["seed"] for record in rmse["per_seed"]] == [0, 1]
    assert rmse["mean_greedy_m"] < rmse["mean_dead_reckoning_m"]


def test_reproduce_fig3_prints_the_summary_table(capsys, tmp_path):
    pytest.importorskip("matplotlib")
    assert main(["reproduce", "fig3", "--output-dir", str(tmp_path), "--seeds", "1"]) == 0
    out = capsys.readouterr().out
    assert "last DGPS fix (t = 20.5 s)" in out and "peak during the outage" in out
    assert "30.5-32.5        #1" in out and "ratio" in out and str(tmp_path / "fig3.json") in out


@pytest.mark.parametrize(
    "text, expected",
    [("mapping=true", True), ("mapping=True", True), ("mapping=False", False), ("robot_sensors=None", None)]
    + [("horizon=30", 30), ("team_reward=0.5", 0.5), ("scenario=corridor", "corridor"), ("time_step_s=inf", math.inf)],
)
def test_config_values_are_json_or_python_constants_else_strings(text, expected):
    key, value = _config_pair(text)
    assert key == text.partition("=")[0]
    assert value == expected and type(value) is type(expected)
