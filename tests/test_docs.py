"""The documentation site builds with warnings as errors (``python -m sphinx -W -b html docs docs/_build/html``),
with a page per registered env, and ``docs/frames`` holds a frame and an episode GIF of every registered env."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from infonav_gym.experiments.render_episode import frame_stem
from infonav_gym.registry import registered_envs

DOCS = Path(__file__).resolve().parent.parent / "docs"


@pytest.fixture(scope="module")
def built_site(tmp_path_factory) -> Path:
    """The site built once into a temporary folder, warnings as errors."""
    for module in ("sphinx", "furo", "myst_parser"):
        pytest.importorskip(module, reason=f'the docs need {module}: pip install ".[docs]"')
    output = tmp_path_factory.mktemp("html")
    built = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(DOCS), str(output)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert built.returncode == 0, built.stderr[-4000:]
    return output


def test_docs_build_without_warnings(built_site):
    assert (built_site / "index.html").is_file()


@pytest.mark.parametrize("env_id", [entry.id for entry in registered_envs()])
def test_every_registered_env_has_a_page_with_its_spaces_config_and_pictures(built_site, env_id):
    page = (built_site / "envs" / f"{frame_stem(env_id)}.html").read_text()
    for section in ("Spaces", "Config", "Episode metrics", "Rendering", "Baselines"):
        assert f">{section}<" in page, f"the page of {env_id} has no {section} section"
    assert "observation_space = " in page and "action_space = " in page
    assert f"{frame_stem(env_id)}.png" in page and f"{frame_stem(env_id)}.gif" in page


@pytest.mark.parametrize("env_id", [entry.id for entry in registered_envs()])
def test_docs_frames_hold_a_frame_and_a_gif_of_every_registered_env(env_id):
    for suffix in (".png", ".gif"):
        path = DOCS / "frames" / f"{frame_stem(env_id)}{suffix}"
        assert path.is_file(), f"{path} is missing: python scripts/render_frames.py --env {env_id}"
