"""``infonav render``: one episode as PREFIX.gif and PREFIX.png, and its one-line errors."""

import json
import sys

import numpy as np
import pytest

from infonav_gym.experiments.cli import main
from infonav_gym.experiments.render_episode import render_episode, strip_indices

PIL = pytest.importorskip("PIL.Image")
pytest.importorskip("matplotlib")
pytest.importorskip("pygame")


def rendered(capsys, tmp_path, *argv) -> tuple[dict, object, object]:
    """Run ``infonav render --json`` into tmp_path/episode; its JSON and the opened GIF and PNG."""
    assert main(["render", "--json", "--output", str(tmp_path / "episode"), *argv]) == 0
    result = json.loads(capsys.readouterr().out)
    return result, PIL.open(tmp_path / "episode.gif"), PIL.open(tmp_path / "episode.png")


def test_the_exploration_env_with_the_planner_writes_an_animated_gif_and_a_strip(capsys, tmp_path):
    argv = ("--env", "cooperative_exploration_v0", "--agents", "planner", "--max-steps", "3")
    result, gif, png = rendered(capsys, tmp_path, *argv, "--config", "render_size_px=240")
    assert (result["steps"], result["frames"]) == (3, 4), "the reset and every step"
    assert gif.n_frames == 4 and max(gif.size) == 240
    gif.seek(3)
    assert len(np.unique(np.asarray(gif.convert("RGB")).reshape(-1, 3), axis=0)) > 8, "a drawn frame, not a blank"
    assert png.size[0] > 400 and len(np.unique(np.asarray(png.convert("RGB")).reshape(-1, 3), axis=0)) > 8
    assert sorted(result["files"]) == sorted(str(tmp_path / f"episode{suffix}") for suffix in (".gif", ".png"))


def test_a_single_agent_env_renders_every_kth_step_and_the_last(capsys, tmp_path):
    argv = ("--env", "infonav/ActiveLocalization-v0", "--agents", "greedy", "--max-steps", "5", "--every", "2")
    result, gif, _ = rendered(capsys, tmp_path, *argv, "--config", "render_size_px=200")
    assert (result["steps"], result["frames"], gif.n_frames) == (5, 4, 4), "steps 0, 2, 4 and the last, 5"


def test_the_rendered_episode_is_the_same_for_the_same_seed():
    first, second = (
        render_episode("infonav/LandmarkSelection-v0", "random", 3, max_steps=4, progress=False) for _ in "ab"
    )
    assert first.steps == second.steps == [0, 1, 2, 3, 4]
    assert all(np.array_equal(a, b) for a, b in zip(first.frames, second.frames))


def test_the_strip_shows_evenly_spaced_frames_with_the_first_and_the_last():
    assert strip_indices(11) == [0, 2, 4, 6, 8, 10]
    assert strip_indices(3) == [0, 1, 2]
    assert strip_indices(1) == [0]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (("--env", "infonav/NoSuchEnv-v0"), "unknown env id 'infonav/NoSuchEnv-v0'"),
        (("--agents", "random,greedy"), "--agents takes one agent to render"),
        (("--agents", "oracle"), "unknown agent 'oracle'"),
    ],
)
def test_bad_arguments_are_one_line_errors_with_exit_code_2(capsys, tmp_path, argv, message):
    with pytest.raises(SystemExit) as error:
        main(["render", "--output", str(tmp_path / "episode"), *argv])
    assert error.value.code == 2
    err = capsys.readouterr().err
    assert message in err and err.startswith("infonav render: error:") and err.count("\n") == 1
    assert not list(tmp_path.iterdir()), "nothing written"


def test_an_output_directory_that_is_a_file_is_a_one_line_error(capsys, tmp_path):
    (tmp_path / "taken").write_text("")
    with pytest.raises(SystemExit) as error:
        main(["render", "--output", str(tmp_path / "taken" / "episode")])
    assert error.value.code == 2
    err = capsys.readouterr().err
    assert "--output" in err and "is a file, not a directory" in err and err.count("\n") == 1


def test_without_pillow_it_is_a_one_line_error_naming_the_render_extra(capsys, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "PIL", None)  # import PIL now raises ImportError
    with pytest.raises(SystemExit) as error:
        main(["render", "--output", str(tmp_path / "episode")])
    assert error.value.code == 2
    err = capsys.readouterr().err
    assert "needs PIL: pip install 'infonav-gym[render]'" in err and err.count("\n") == 1
