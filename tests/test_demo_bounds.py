"""``infonav demo`` and ``--plot`` files: steps of one corridor episode, a progress bar, the file said is written."""

import json

import pytest

from infonav_gym.experiments import benchmark, demo
from infonav_gym.experiments.cli import main


def test_demo_steps_are_one_corridor_episode(capsys):
    with pytest.raises(SystemExit) as stopped:
        main(["demo", "--steps", str(demo.DEMO_HORIZON + 1)])
    assert stopped.value.code == 2
    assert "argument --steps: must be an integer from 1 to 200, got '201'" in capsys.readouterr().err
    with pytest.raises(ValueError, match=r"steps must be in \[1, 200\] \(one corridor episode\), got 201"):
        demo.run_demo(steps=demo.DEMO_HORIZON + 1)


def test_a_whole_episode_demo_shows_a_progress_bar_on_stderr_unless_json(capsys, monkeypatch):
    monkeypatch.setattr(demo, "PROGRESS_DELAY_S", 0.0)  # as if the demo ran longer than the delay
    assert main(["demo", "--steps", str(demo.DEMO_HORIZON)]) == 0
    out, err = capsys.readouterr()
    assert "demo: 100%" in err and f"{2 * demo.DEMO_HORIZON}/{2 * demo.DEMO_HORIZON}" in err
    assert "total information gathered" in out and "demo:" not in out
    assert main(["demo", "--steps", "3", "--json"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and len(json.loads(out)["runs"]["greedy"]) == 3


def test_demo_plot_says_the_file_it_writes(capsys, tmp_path):
    pytest.importorskip("matplotlib")
    assert main(["demo", "--steps", "1", "--plot", str(tmp_path / "x")]) == 0
    assert capsys.readouterr().out.endswith(f"wrote {tmp_path / 'x.png'}\n")
    assert (tmp_path / "x.png").read_bytes()[:4] == b"\x89PNG" and not (tmp_path / "x").exists()


def test_benchmark_plot_says_the_file_it_writes(capsys, tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    figures = {"cartpole_steps_per_s": 1e5, "cartpole_vector_4_steps_per_s": 2e5}
    canned = {"figures": figures, "goals": {}, "goals_met": {}, "notes": []}
    monkeypatch.setattr(benchmark, "run_benchmark", lambda **kwargs: dict(canned))
    assert main(["benchmark", "--vector-sizes", "4", "--plot", str(tmp_path / "curves")]) == 0
    assert capsys.readouterr().out.endswith(f"wrote {tmp_path / 'curves.png'}\n")
    assert (tmp_path / "curves.png").read_bytes()[:4] == b"\x89PNG"


def test_a_plot_stem_that_is_a_directory_is_refused_before_the_demo(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(demo, "run_demo", lambda **kwargs: pytest.fail("the demo ran"))
    (tmp_path / "x.png").mkdir()
    with pytest.raises(SystemExit) as stopped:
        main(["demo", "--plot", str(tmp_path / "x")])
    assert stopped.value.code == 2
    assert f"--plot {tmp_path / 'x'}: {tmp_path / 'x.png'} is a directory, not a file" in capsys.readouterr().err
