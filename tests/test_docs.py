"""The documentation site builds with warnings as errors (``python -m sphinx -W -b html docs docs/_build/html``):
a page per registered env, the API reference, every ``infonav`` command and the paper's figures; ``docs/frames``
holds a frame and an episode GIF of every registered env."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from infonav_gym.experiments.cli import build_parser
from infonav_gym.experiments.render_episode import frame_stem
from infonav_gym.registry import registered_envs

DOCS = Path(__file__).resolve().parent.parent / "docs"
sys.path.insert(0, str(DOCS / "_ext"))
from cli_page import subcommands  # noqa: E402  (docs/_ext, above)

PUBLIC_NAMES = (  # the public contract's names (ARCHITECTURE.md): each documented on the API page
    "infonav_gym.make_env",
    "infonav_gym.registry.register",
    "infonav_gym.information.gaussian_entropy",
    "infonav_gym.information.information_metric",
    "infonav_gym.information.mutual_information",
    "infonav_gym.information.expected_information_gain",
    "infonav_gym.information.histogram_entropy",
    "infonav_gym.envs.LandmarkSelectionEnv",
    "infonav_gym.multi.cooperative_localization_v0.parallel_env",
    "infonav_gym.multi.cooperative_exploration_v0.env",
    "infonav_gym.estimation.PoseEKF",
    "infonav_gym.estimation.JointEKF",
    "infonav_gym.world.register_scenario",
    "infonav_gym.registration.icp",
    "infonav_gym.registration.RegistrationResult",
    "infonav_gym.datasets.load",
    "agents.GreedyEntropyAgent",
)


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
    page = (built_site / "generated" / "envs" / f"{frame_stem(env_id)}.html").read_text()
    for section in ("Spaces", "Config", "Episode metrics", "Rendering", "Baselines"):
        assert f">{section}<" in page, f"the page of {env_id} has no {section} section"
    assert "observation_space = " in page and "action_space = " in page
    assert f"{frame_stem(env_id)}.png" in page and f"{frame_stem(env_id)}.gif" in page


def test_the_api_page_documents_the_public_names(built_site):
    documented = set(
        re.findall(r'<dt class="sig sig-object py" id="([^"]+)"', (built_site / "generated" / "api.html").read_text())
    )
    assert not set(PUBLIC_NAMES) - documented


def test_the_cli_page_has_a_section_per_command_of_the_parser(built_site):
    page = (built_site / "generated" / "cli.html").read_text()
    commands, parsers = [], [build_parser()]
    while parsers:
        parser = parsers.pop()
        for sub, _ in subcommands(parser).values():
            commands.append(sub.prog)
            parsers.append(sub)
    assert {"infonav evaluate", "infonav render", "infonav replay mrclam"} <= set(commands)
    for command in commands:  # its section's heading, `infonav replay mrclam`, is its anchor
        assert f'id="{command.replace(" ", "-")}"' in page, command


def test_the_figures_page_shows_every_committed_figure(built_site):
    page = (built_site / "generated" / "figures.html").read_text()
    for figure in (DOCS.parent / "results").glob("fig*.png"):
        assert f'src="../_images/{figure.name}"' in page, figure.name


@pytest.mark.parametrize("env_id", [entry.id for entry in registered_envs()])
def test_docs_frames_hold_a_frame_and_a_gif_of_every_registered_env(env_id):
    for suffix in (".png", ".gif"):
        path = DOCS / "frames" / f"{frame_stem(env_id)}{suffix}"
        assert path.is_file(), f"{path} is missing: python scripts/render_frames.py --env {env_id}"
