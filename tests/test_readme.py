"""README's Python snippets run and print what they compute; its env table matches the registry and results/."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from infonav_gym.registry import GYMNASIUM, env_entry, registered_envs

README = Path(__file__).resolve().parent.parent / "README.md"
SNIPPETS = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_has_snippets():
    assert len(SNIPPETS) >= 3


@pytest.mark.parametrize("index", range(len(SNIPPETS)))
def test_snippet_runs_and_prints(index, tmp_path):
    completed = subprocess.run(
        [sys.executable, "-c", SNIPPETS[index]],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "SDL_VIDEODRIVER": "dummy"},
    )
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert completed.stdout.strip(), f"README snippet {index} prints nothing:\n{SNIPPETS[index]}"


def _env_table() -> dict[str, dict[str, str]]:
    """README's env table: env id (its first column, in backticks) -> the row's cells by header."""
    section = README.read_text().split("## Environments\n", 1)[1].split("\n## ", 1)[0]
    lines = [line for line in section.splitlines() if line.startswith("|")]
    header = [cell.strip() for cell in lines[0].strip("|").split("|")]
    rows = {}
    for line in lines[2:]:
        row = dict(zip(header, (cell.strip() for cell in line.strip("|").split("|")), strict=True))
        env_id = re.fullmatch(r"`([^`]+)`", row["id"]).group(1)
        assert env_id not in rows, f"README's env table names {env_id} twice"
        rows[env_id] = row
    return rows


def _result_agents(path: Path, env_id: str) -> set[str]:
    """The agents a committed ``infonav evaluate`` table holds, as the env table names them."""
    text = path.read_text()
    assert text.startswith(f"# {env_id},"), f"{path.name} is not an evaluation of {env_id}"
    names = {"random": "random", "greedy": "greedy", "planner": "planner", "ppo": "PPO", "rllib": "RLlib PPO"}
    first_cells = re.findall(r"^\| ([^|]+?) \|", text, flags=re.M)  # the header, its rule, then one row per agent
    return {names[agent.partition(":")[0]] for agent in first_cells[2:]}


def test_env_table_lists_every_registered_env_once_and_no_other():
    assert sorted(_env_table()) == sorted(entry.id for entry in registered_envs())


def test_env_table_api_and_native_vector_env_match_the_registry():
    for env_id, row in _env_table().items():
        entry = env_entry(env_id)
        assert row["API"] == ("Gymnasium" if entry.api == GYMNASIUM else "PettingZoo"), env_id
        vector = "no" if entry.vector_entry_point is None else f"`{entry.vector_entry_point.rpartition(':')[2]}`"
        assert row["native vector env"] == vector, env_id


def test_env_table_agents_are_those_of_the_committed_results():
    for env_id, row in _env_table().items():
        paths = [README.parent / path for path in re.findall(r"`([^`]+)`", row["results"])]
        assert paths and all(path.is_file() for path in paths), (env_id, row["results"])
        found = set().union(*(_result_agents(path, env_id) for path in paths))
        assert set(row["agents in the committed results"].split(", ")) == found, env_id
