"""The documentation site builds with warnings as errors (``python -m sphinx -W -b html docs docs/_build/html``):
a page per registered env, the API reference, every ``infonav`` command and the paper's figures; ``docs/frames``
holds a frame and an episode GIF of every registered env; a headless Chromium renders the index and an env page."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from infonav_gym.experiments.cli import build_parser
from infonav_gym.experiments.render_episode import frame_stem
from infonav_gym.registry import env_entry, registered_envs

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
    for key in env_entry(env_id).load().default_config():
        assert f'<span class="pre">{key}</span>' in page, f"the config table of {env_id} has no row for {key}"
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


BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
PROBE = """<html><head><title>probe</title></head><body><pre id="report">not loaded</pre>
<iframe id="page" src="{url}" width="1280" height="2000"></iframe>
<script>
document.getElementById("page").onload = function () {{
  const page = this.contentDocument;
  document.getElementById("report").textContent = JSON.stringify({{
    title: page.title,
    tables: Array.from(page.querySelectorAll("table"), table => table.rows[0].innerText),
    images: Array.from(page.images, image => ({{src: image.getAttribute("src"), width: image.naturalWidth}})),
  }});
}};
</script></body></html>
"""  # reports, once the page and its images have loaded, its title, the header rows of its tables and its images


@pytest.fixture(scope="module")
def browser() -> str:
    """A Chromium on PATH, or a skip that says how to install one."""
    found = next(filter(None, map(shutil.which, BROWSERS)), None)
    if found is None:
        pytest.skip("no Chromium on PATH: install Debian's package (apt-get install chromium) for the browser check")
    return found


def headless(browser: str, *arguments: str) -> str:
    """What a headless Chromium run prints on stdout (root needs --no-sandbox)."""
    command = [browser, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", *arguments]
    return subprocess.run(command, capture_output=True, text=True, timeout=120, check=True).stdout


def rendered(browser: str, page: Path, tmp_path: Path) -> dict:
    """The title, table headers and images (their natural widths: 0 if not loaded) of ``page`` as Chromium shows it."""
    probe = tmp_path / "probe.html"
    probe.write_text(PROBE.format(url=page.as_uri()))
    budget = ["--allow-file-access-from-files", "--virtual-time-budget=20000", "--dump-dom", probe.as_uri()]
    report = re.search(r'<pre id="report">(.*?)</pre>', headless(browser, *budget), flags=re.S).group(1)
    return json.loads(report.replace("&amp;", "&").replace("&lt;", "<").replace("&gt;", ">"))


def screenshot_is_a_page(browser: str, page: Path, tmp_path: Path) -> bool:
    """Whether Chromium's screenshot of ``page`` shows text and pictures: many colours, not mostly one."""
    from PIL import Image

    shot = tmp_path / "shot.png"
    headless(browser, "--window-size=1280,1600", f"--screenshot={shot}", page.as_uri())
    with Image.open(shot) as image:
        pixels = np.asarray(image.convert("RGB")).reshape(-1, 3)
    colours, counts = np.unique(pixels, axis=0, return_counts=True)
    return len(colours) > 100 and counts.max() < 0.95 * len(pixels)


def test_chromium_renders_the_index(browser, built_site, tmp_path):
    page = rendered(browser, built_site / "index.html", tmp_path)
    assert page["title"].startswith("infonav-gym")
    assert screenshot_is_a_page(browser, built_site / "index.html", tmp_path)


def test_chromium_renders_an_env_page_with_its_spaces_table_and_pictures(browser, built_site, tmp_path):
    from PIL import Image

    env_id = registered_envs()[0].id
    path = built_site / "generated" / "envs" / f"{frame_stem(env_id)}.html"
    page = rendered(browser, path, tmp_path)
    assert page["title"].startswith(env_id)
    assert any(
        header.split() == ["who", "space", "class", "shape", "dtype", "bounds", "(lowest,", "highest)"]
        for header in page["tables"]
    ), page["tables"]
    widths = {Path(image["src"]).name: image["width"] for image in page["images"]}
    for suffix in (".png", ".gif"):
        with Image.open(DOCS / "frames" / f"{frame_stem(env_id)}{suffix}") as picture:
            assert widths[f"{frame_stem(env_id)}{suffix}"] == picture.width  # loaded, at its own size
    assert screenshot_is_a_page(browser, path, tmp_path)
