"""The vector-env throughput benchmark: discovery, random valid actions, figures, memory, VMAS rows, plot, errors.

Figures are checked for their names, signs and ratios, never for speed.
"""

from __future__ import annotations

import importlib.util
import json
import sys

import gymnasium as gym
import numpy as np
import pytest
from scipy import stats

from infonav_gym.experiments import benchmark, startup_timing
from infonav_gym.experiments.benchmark import (
    GOALS,
    env_step_figures,
    goal_fractions,
    lower_is_better,
    memory_figures,
    plot_throughput,
    throughput_curves,
)
from infonav_gym.experiments.cli import main
from infonav_gym.experiments.vector_timing import (
    VectorRun,
    check_vector_sizes,
    parse_vector_sizes,
    random_valid_actions,
    vector_env_ids,
    vmas_missing,
)
from infonav_gym.registry import register, unregister

LANDMARKS = "infonav/LandmarkSelection-v0"
HAS_VMAS = importlib.util.find_spec("vmas") is not None


@pytest.fixture
def no_vmas(monkeypatch):
    """``import vmas`` fails, as where it is not installed."""
    monkeypatch.setitem(sys.modules, "vmas", None)


def test_discovery_finds_every_registered_native_vector_env():
    ids = vector_env_ids()  # a Gymnasium env's and a PettingZoo team env's vector envs alike
    assert {
        LANDMARKS,
        "infonav/ActiveLocalization-v0",
        "infonav/SensorSelection-v0",
        "infonav/RangeRegistration-v0",
        "cooperative_localization_v0",
    } <= set(ids)
    toy = "toy/VectorBeacon-v0"
    register(toy, "toy.beacon:BeaconEnv", vector_entry_point="toy.beacon:BeaconVectorEnv")  # imported only when made
    try:
        assert vector_env_ids()[-1] == toy
    finally:
        unregister(toy)
    assert toy not in vector_env_ids()


def test_random_valid_actions_are_uniform_over_each_rows_valid_actions():
    masks = np.array([[True, False, True, True], [False, False, True, False], [True, True, True, True]])
    rng = np.random.default_rng(0)
    draws = np.stack([random_valid_actions(masks, rng) for _ in range(3000)])
    assert draws.shape == (3000, 3) and masks[np.arange(3), draws].all()
    assert (draws[:, 1] == 2).all()
    for row in (0, 2):
        counts = np.bincount(draws[:, row], minlength=4)[masks[row]]
        assert stats.chisquare(counts).pvalue > 1e-3
    team_masks = rng.random((5, 3, 4)) < 0.5  # a team env's (N, R, K): one action per robot
    team_masks[..., 0] = True  # its no-op is always valid
    team_actions = random_valid_actions(team_masks, rng)
    assert team_actions.shape == (5, 3)
    assert np.take_along_axis(team_masks, team_actions[..., None], axis=-1).all()


def test_random_valid_actions_drive_the_landmark_vector_env_without_a_masked_action():
    env = gym.make_vec(LANDMARKS, num_envs=6, vectorization_mode="vector_entry_point", invalid_action="raise")
    env.reset(seed=3)
    rng = np.random.default_rng(0)
    information = 0.0
    for _ in range(250):  # through the 200-step horizon's autoreset; a masked action would raise ValueError
        information += env.step(random_valid_actions(env.action_masks(), rng))[1].sum()
    assert information > 0  # the steps observed landmarks, they were not no-ops


def test_a_vector_env_is_reset_once_and_its_rounds_go_on_through_autoresets():
    calls = {"start": 0, "step": 0}
    run = VectorRun(
        8, start=lambda: calls.update(start=calls["start"] + 1), step=lambda: calls.update(step=calls["step"] + 1)
    )
    measure = benchmark._vector_stepper(run, seconds=0.001)
    rates = [measure() for _ in range(3)]
    assert calls["start"] == 1 and calls["step"] >= 3 and min(rates) > 0


def test_vector_figures_have_the_right_keys_and_are_positive(no_vmas):
    figures = env_step_figures([LANDMARKS], rounds=1, seconds_per_round=0.01, progress=False, vector_sizes=(1, 3))
    names = ["landmark_selection"] + [f"{env}_vector_{n}" for n in (1, 3) for env in ("landmark_selection", "cartpole")]
    ours = [f"landmark_selection_vector_{n}" for n in (1, 3)]
    assert set(figures) == {"cartpole_steps_per_s"} | {
        f"{name}{suffix}" for name in names for suffix in ("_steps_per_s", "_vs_cartpole_ratio")
    } | {f"{name}_vs_single_ratio" for name in ours}
    assert all(value > 0 for value in figures.values())
    for name in names:  # one round: the ratio is that round's quotient
        ratio = figures[f"{name}_steps_per_s"] / figures["cartpole_steps_per_s"]
        assert figures[f"{name}_vs_cartpole_ratio"] == pytest.approx(ratio)
    for name in ours:  # env-steps per second of the vector env over its single env's
        ratio = figures[f"{name}_steps_per_s"] / figures["landmark_selection_steps_per_s"]
        assert figures[f"{name}_vs_single_ratio"] == pytest.approx(ratio)


def test_without_vmas_its_rows_are_absent_with_a_note(no_vmas, monkeypatch):
    assert "pip install 'infonav-gym[bench]'" in vmas_missing()
    for heavy in (
        "sensor_figures",
        "icp_figures",
        "map_step_figures",
        "_ppo_figures",
        "evaluation_workers_figures",
        "rllib_runner_figures",
        "training_figures",
        "startup_figures",
    ):
        monkeypatch.setattr(benchmark, heavy, lambda *args: {})
    monkeypatch.setattr(benchmark, "rllib_missing", lambda: None)  # this test is about VMAS's note alone
    monkeypatch.setattr(benchmark, "greedy_decision_us", lambda: 1.0)
    monkeypatch.setattr(benchmark, "registration_peers_missing", lambda: None)
    monkeypatch.setattr(benchmark, "kb_per_env", lambda env_id, num_envs, steps, seed, seconds: 50.0)
    monkeypatch.setattr(benchmark, "benchmarked_env_ids", lambda: [LANDMARKS])
    result = benchmark.run_benchmark(rounds=1, seconds_per_round=0.01, progress=False, vector_sizes=(2, 256))
    assert not [name for name in result["figures"] if "vmas" in name]
    assert result["notes"] == [vmas_missing()] and result["vector_sizes"] == [2, 256]
    assert result["figures"]["landmark_selection_vector_256_kb_per_env"] == 50.0
    met = result["goals_met"]
    assert met["cooperative_localization_vector_256_vs_vmas_ratio"] is None  # not measured: no VMAS, no team env
    assert met["active_localization_vector_1024_kb_per_env"] is None
    ratio = result["figures"]["landmark_selection_vector_256_vs_cartpole_ratio"]
    assert met["landmark_selection_vector_256_vs_cartpole_ratio"] == (ratio >= 2.0)


@pytest.mark.skipif(not HAS_VMAS, reason="vmas is not installed (the bench extra)")
def test_with_vmas_its_navigation_rows_and_our_ratios_against_it():
    torch = pytest.importorskip("torch")
    threads = torch.get_num_threads()
    figures = env_step_figures([LANDMARKS], rounds=1, seconds_per_round=0.01, progress=False, vector_sizes=(2,))
    assert torch.get_num_threads() == threads  # VMAS steps on one thread, the caller's setting is back
    vmas, ours = figures["vmas_navigation_2_steps_per_s"], figures["landmark_selection_vector_2_steps_per_s"]
    assert vmas > 0 and figures["landmark_selection_vector_2_vs_vmas_ratio"] == pytest.approx(ours / vmas)
    assert figures["vmas_navigation_2_vs_cartpole_ratio"] == pytest.approx(vmas / figures["cartpole_steps_per_s"])


def test_memory_per_sub_env_is_measured_in_a_subprocess_and_lower_is_better():
    figures = memory_figures(4, [LANDMARKS], steps=5)
    assert list(figures) == ["landmark_selection_vector_4_kb_per_env"]
    assert figures["landmark_selection_vector_4_kb_per_env"] > 0
    assert lower_is_better("landmark_selection_vector_1024_kb_per_env")
    assert not lower_is_better("landmark_selection_vector_1024_steps_per_s")
    assert lower_is_better("cold_start_s") and not lower_is_better("cartpole_steps_per_s")
    assert lower_is_better("cold_start_all_envs_s")


def test_throughput_curves_and_the_plot_file(tmp_path):
    figures = {
        "cartpole_steps_per_s": 1.5e5,
        "landmark_selection_steps_per_s": 6e3,
        "landmark_selection_vector_16_steps_per_s": 2e4,
        "landmark_selection_vector_1_steps_per_s": 2e3,
        "landmark_selection_vector_16_vs_cartpole_ratio": 0.13,
        "cartpole_vector_1_steps_per_s": 3e4,
        "landmark_selection_vector_1024_kb_per_env": 250.0,
        "cold_start_s": 2 * GOALS["cold_start_s"],
    }
    assert goal_fractions(figures) == {  # only the measured goals; a time's goal over the figure
        "landmark_selection_vector_1024_kb_per_env": GOALS["landmark_selection_vector_1024_kb_per_env"] / 250.0,
        "cold_start_s": 0.5,
    }
    assert throughput_curves(figures) == {
        "landmark_selection_vector": {16: 2e4, 1: 2e3},
        "cartpole_vector": {1: 3e4},
    }
    path = plot_throughput(figures, tmp_path / "throughput.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match="CURVE_N_steps_per_s.*cartpole_steps_per_s"):
        plot_throughput({"cartpole_steps_per_s": 1.0}, tmp_path / "none.png")


def test_benchmark_plot_option_writes_the_plot_of_the_figures(tmp_path, capsys, monkeypatch):
    figures = {"cartpole_steps_per_s": 1e5, "cartpole_vector_4_steps_per_s": 2e5}
    canned = {"figures": figures, "goals": {}, "goals_met": {}, "notes": []}
    runs = []
    monkeypatch.setattr(benchmark, "run_benchmark", lambda **kwargs: runs.append(kwargs) or dict(canned))
    path = tmp_path / "throughput.png"
    assert main(["benchmark", "--vector-sizes", "4", "--plot", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["files"] == [str(path)]
    assert path.read_bytes()[:4] == b"\x89PNG" and runs[0]["vector_sizes"] == (4,)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0,16", r"--vector-sizes: each number of sub-envs must be an integer from 1 to 65536, got 0 in \(0, 16\)"),
        ("1,x", r"--vector-sizes: expected comma-separated integers >= 1 such as '1,16,256', got 'x' in '1,x'"),
        ("", r"got '' in ''"),
        ("16,-4", r"got -4 in \(16, -4\)"),
    ],
)
def test_bad_vector_sizes_are_named(text, message, capsys):
    with pytest.raises(ValueError, match=message):
        parse_vector_sizes(text)
    with pytest.raises(SystemExit) as stopped:
        main(["benchmark", "--vector-sizes", text])
    assert stopped.value.code == 2
    assert "argument --vector-sizes:" in capsys.readouterr().err


def test_bad_vector_sizes_given_in_python_are_named():
    with pytest.raises(ValueError, match="vector sizes: expected at least one number of sub-envs, got none"):
        check_vector_sizes([])
    with pytest.raises(ValueError, match=r"got True in \(True,\)"):
        check_vector_sizes([True])
    with pytest.raises(ValueError, match=r"got 2.5 in \(1, 2.5\)"):
        env_step_figures([], rounds=1, seconds_per_round=0.01, progress=False, vector_sizes=(1, 2.5))


def test_a_plot_path_that_cannot_be_written_stops_before_the_run(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(benchmark, "run_benchmark", lambda **kwargs: pytest.fail("the benchmark ran"))
    with pytest.raises(SystemExit) as stopped:
        main(["benchmark", "--plot", str(tmp_path)])
    assert stopped.value.code == 2
    assert f"--plot {tmp_path} is a directory" in capsys.readouterr().err


def test_a_failing_first_step_process_is_a_runtime_error_quoting_it(monkeypatch):
    monkeypatch.setattr(startup_timing, "FIRST_STEP_SCRIPT", "raise SystemExit('no envs here')")
    with pytest.raises(RuntimeError, match=r"the first-step process failed \(exit 1\): no envs here"):
        startup_timing.first_step_seconds("/nonexistent-cache-dir", ["infonav/LandmarkSelection-v0"])
