"""Every tutorial in ``docs/tutorials`` runs as written and prints what its page says it prints.

A page runs as one script in a fresh subprocess, in a temporary directory: its ```python blocks in page order, and
between them, where the page has them, the lines of its ```bash / ```console blocks that start with ``infonav ``
(run by the shell, with this interpreter's ``infonav`` first on ``PATH``; their output printed after a ``$ command``
line). A block right after a MyST comment line ``% not run: REASON`` is left out (a Ray cluster's address, a long
run); each test then checks the key lines and numbers of the output against the page.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

TUTORIALS = Path(__file__).resolve().parent.parent / "docs" / "tutorials"
DEFAULT_MRCLAM = Path(__file__).resolve().parents[1] / ".." / "shared" / "datasets" / "MRCLAM_Dataset6"
MRCLAM = Path(os.environ.get("INFONAV_MRCLAM_DATASET6", DEFAULT_MRCLAM))  # as tests/test_mrclam.py finds it
BLOCK = re.compile(r"^(?P<skip>% not run: \S[^\n]*\n)?```(?P<language>\w+)\n(?P<code>.*?)^```$", flags=re.M | re.S)
COMMAND_RUNNER = '''\
import subprocess as _subprocess


def _infonav(command):
    """Run a command of the page in the shell, print it and what it printed; stop the page if it fails."""
    print("$ " + command, flush=True)
    done = _subprocess.run(command, shell=True, text=True, capture_output=True)
    print(done.stdout, flush=True)
    if done.returncode:
        raise SystemExit(f"{command!r} exited with {done.returncode}:\\n{done.stderr[-3000:]}")

'''


def page_script(page: Path) -> str:
    """The Python script that runs ``page``: its Python blocks and its ``infonav`` command lines, in page order."""
    parts = [COMMAND_RUNNER]
    for block in BLOCK.finditer(page.read_text()):
        if block["skip"]:
            continue
        if block["language"] == "python":
            parts.append(block["code"])
        elif block["language"] in ("bash", "console"):
            lines = re.sub(r" *\\\n\s*", " ", block["code"]).splitlines()  # a command continued over lines is one line
            commands = [line.removeprefix("$ ") for line in lines]
            parts += [f"_infonav({command!r})\n" for command in commands if command.startswith("infonav ")]
    return "\n".join(parts)


def run_page(name: str, tmp_path: Path, **environment: str) -> str:
    """Run the tutorial ``name`` (see the module); its stdout, after checking that it ran to its end."""
    script = tmp_path / f"{name}.py"
    script.write_text(page_script(TUTORIALS / f"{name}.md"))
    path = os.pathsep.join([str(Path(sys.executable).parent), os.environ.get("PATH", "")])
    done = subprocess.run(
        [sys.executable, str(script)],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, "PATH": path, "SDL_VIDEODRIVER": "dummy", **environment},
    )
    assert done.returncode == 0, f"{name}: {done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout


def number(output: str, pattern: str) -> float:
    """The number the first group of ``pattern`` finds in ``output``."""
    found = re.search(pattern, output, flags=re.M)
    assert found, f"no line matches {pattern!r} in:\n{output[-3000:]}"
    return float(found.group(1))


def test_every_tutorial_is_in_the_index_and_tested_here():
    pages = sorted(page.stem for page in TUTORIALS.glob("*.md") if page.stem != "index")
    index = (TUTORIALS / "index.md").read_text()
    assert all(f"\n{page}\n" in index for page in pages), "a tutorial missing from the toctree of docs/tutorials"
    tested = {name.removeprefix("test_") for name in globals() if name.startswith("test_")}
    assert set(pages) <= tested, f"tutorials without a test here: {set(pages) - tested}"
    assert "\ntutorials/index\n" in (TUTORIALS.parent / "index.md").read_text()


def test_page_script_takes_python_and_infonav_lines_in_order_and_leaves_out_blocks_not_run(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "```python\nx = 1\n```\n\n```bash\npip install x\ninfonav evaluate \\\n  --episodes 2\n```\n\n"
        "% not run: needs a cluster\n```bash\ninfonav train --address HEAD:6379\n```\n\n"
        "```console\n$ infonav demo\n```\n\n```text\ninfonav output\n```\n\n```python\nprint(x)\n```\n"
    )
    script = page_script(page).removeprefix(COMMAND_RUNNER)
    assert script.split("\n") == [
        "",
        "x = 1",
        "",
        "_infonav('infonav evaluate --episodes 2')",
        "",
        "_infonav('infonav demo')",
        "",
        "print(x)",
        "",
    ]


def test_make_an_env(tmp_path):
    output = run_page("make_an_env", tmp_path)
    assert "Discrete(8) (50,)" in output and "valid landmarks: [0 1 2 3]" in output
    assert re.search(r"^expected MI \[nats\]: \[0\.266 0\.245 0\.34 +0\.236 0\. ", output, flags=re.M)
    greedy = number(output, r"^greedy: 40 steps, cumulative_mi ([\d.]+) nats")
    random = number(output, r"^random: 40 steps, cumulative_mi ([\d.]+) nats")
    assert 8.5 < greedy < 9.5 and 8.0 < random < greedy  # on the corridor greedy gathers the most
    assert "Episode metrics: cumulative_mi, final_pose_entropy, pose_rmse_m" in output
    assert "greedy: 4 episodes, seeds 0..3" in output
    cli_greedy = number(output, r"^\| greedy \| ([\d.]+) ±")
    assert cli_greedy > number(output, r"^\| random \| ([\d.]+) ±")


@pytest.mark.slow
def test_train_maskable_ppo(tmp_path):
    output = run_page("train_maskable_ppo", tmp_path)
    assert "LandmarkSelectionVectorEnv 16 Discrete(8) (16, 8)" in output
    assert number(output, r"^greedy on 16 copies: ([\d.]+) nats per copy") > 3.0
    assert "MaskablePPO trained 4096 steps" in output and (tmp_path / "landmark_ppo" / "model.zip").is_file()
    assert re.search(
        r"^trained MaskablePPO on infonav/LandmarkSelection-v0 \(16 envs, native\) for 4096 ", output, re.M
    )
    assert (tmp_path / "models" / "landmark_ppo" / "model.zip").is_file()


@pytest.mark.slow
def test_evaluate_against_greedy(tmp_path):
    output = run_page("evaluate_against_greedy", tmp_path)
    cli_greedy = number(output, r"^\| greedy \| ([\d.]+) ±")
    assert 5.0 < cli_greedy < 15.0 and re.search(r"^\| ppo:models/landmark_ppo \| [\d.]+ ±", output, re.M)
    assert {"landmark_ppo_vs_greedy.md", "landmark_ppo_vs_greedy.json"} <= set(os.listdir(tmp_path / "results"))
    assert "seeds: [0, 1, 2, 3, 4, 5, 6, 7, 8, 9]" in output
    share = number(output, r"^PPO gathers ([\d.]+)% of greedy's information")
    assert 50 < share < 110
    assert "the same numbers as the command line: True" in output


def test_add_a_scenario(tmp_path):
    output = run_page("add_a_scenario", tmp_path)
    assert "greedy gathers 6.82 nats along the roadside" in output
    assert "sub-env 1 runs 'roadside' with 4 landmarks" in output
    assert number(output, r"^greedy: ([\d.]+) nats") > number(output, r"^random: ([\d.]+) nats")


def test_the_tutorial_env_is_at_most_80_lines_with_its_registration():
    """The tutorial's env (its first code block: imports, state, scenario, classes, registration) in <= 80 lines."""
    code = next(block["code"] for block in BLOCK.finditer((TUTORIALS / "write_a_vector_env.md").read_text()))
    lines = [line for line in code.splitlines() if line.strip()]
    assert "class Beacon(EnvScenario)" in code and "infonav_gym.register(" in lines[-1]
    assert len(lines) <= 80, f"{len(lines)} non-blank lines"


@pytest.mark.slow
def test_write_a_vector_env(tmp_path):
    output = run_page("write_a_vector_env", tmp_path)
    assert "BeaconVectorEnv (4, 3) Discrete(4)" in output
    assert "check_env: passed" in output
    assert "sub-env 2 equals the single env seeded 12: True" in output
    assert "realized MI = expected MI of the chosen beacon: True" in output
    assert number(output, r"^\| greedy \| ([\d.]+) ±") > number(output, r"^\| random \| ([\d.]+) ±")
    assert "trained beacon_ppo/model.zip" in output  # MaskablePPO on its native vector env


@pytest.mark.slow
def test_ray_cluster(tmp_path):
    output = run_page("ray_cluster", tmp_path)
    assert "Ray CPUs: 2.0" in output and "the same numbers on Ray: True" in output
    assert number(output, r"^RLlib trained (\d+) env steps") >= 1000
    assert number(output, r"^rllib:landmark_rllib: ([\d.]+) nats") > 0
    assert number(output, r"^\| greedy \| ([\d.]+) ±") > 0  # the command line's evaluation on its own local Ray


def test_replay_mrclam(tmp_path):
    if not MRCLAM.is_dir():
        pytest.skip(f"no MRCLAM Dataset 6 at {MRCLAM}: set INFONAV_MRCLAM_DATASET6 to its directory")
    output = run_page("replay_mrclam", tmp_path, MRCLAM_DIR=str(MRCLAM.resolve()))
    assert "robots (1, 2, 3, 4, 5), 15 landmarks, 888 s of logs" in output
    rmse = number(output, r"^greedy, one reading per measurement time: position RMSE ([\d.]+) m")
    dead_reckoning = number(output, r"dead reckoning ([\d.]+) m")
    assert 0.05 < rmse < 0.15 < dead_reckoning
    assert re.search(r"^\| greedy \| 1 \| 0\.\d\d\d \|", output, re.M)
    assert (tmp_path / "replay" / "first_minute.md").is_file()
