"""README's and the docs pages' Python snippets run and print what their comments say; README stays short, its links
resolve, its env table matches the registry and results/, and its results table the committed files."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from infonav_gym.registry import GYMNASIUM, env_entry, registered_envs

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
SNIPPET = re.compile(r"```python\n(.*?)```", flags=re.S)
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]  # the docs' top-level pages (tutorials test their own)
SNIPPETS = {
    f"{page.name}:{index}": snippet for page in PAGES for index, snippet in enumerate(SNIPPET.findall(page.read_text()))
}
README_MAX_BYTES = 15_000


def promised_output(snippet: str) -> list[str]:
    """What a snippet's comments say it prints: the text after ``prints:`` in each comment that has one."""
    return re.findall(r"#.*?\bprints: (.+)$", snippet, flags=re.M)


def test_readme_has_snippets_each_promising_its_output():
    readme_snippets = SNIPPET.findall(README.read_text())
    assert len(readme_snippets) >= 3
    for snippet in readme_snippets:
        assert promised_output(snippet), f"a README snippet says nowhere what it prints (# prints: ...):\n{snippet}"


@pytest.mark.parametrize("name", SNIPPETS)
def test_snippet_runs_and_prints_what_its_comments_say(name, tmp_path):
    completed = subprocess.run(
        [sys.executable, "-c", SNIPPETS[name]],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "SDL_VIDEODRIVER": "dummy"},
    )
    assert completed.returncode == 0, completed.stderr[-2000:]
    assert completed.stdout.strip(), f"snippet {name} prints nothing:\n{SNIPPETS[name]}"
    for promised in promised_output(SNIPPETS[name]):
        assert promised in completed.stdout, f"snippet {name} does not print {promised!r}:\n{completed.stdout}"


def test_readme_is_short():
    size = len(README.read_bytes())
    assert size < README_MAX_BYTES, f"README.md is {size} bytes, more than {README_MAX_BYTES}: move text into docs/"


def test_every_relative_link_of_the_readme_points_to_a_file():
    targets = re.findall(r"\]\(([^)\s]+)\)", README.read_text())  # [text](target) and ![alt](target)
    relative = [target.partition("#")[0] for target in targets if not re.match(r"[a-z]+:|#", target)]
    assert relative, "README links to nothing in the repository"
    missing = [target for target in relative if not (ROOT / target).is_file()]
    assert not missing, f"README links to files that do not exist: {missing}"


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
    names = {
        "random": "random",
        "greedy": "greedy",
        "nearest": "nearest",
        "everything": "everything",
        "planner": "planner",
        "ppo": "PPO",
        "rllib": "RLlib PPO",
    }
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


def test_results_table_is_the_committed_leaderboard():
    section = README.read_text().split("## Results\n", 1)[1].split("\n## ", 1)[0]
    table = [line for line in section.splitlines() if line.startswith("|")]
    committed = (ROOT / "results" / "leaderboard.md").read_text().splitlines()
    assert len(table) > 2 and table == committed[committed.index(table[0]) :][: len(table)]
    rows = {line.split("|")[1].strip() for line in table[2:]}
    assert rows == {entry.id for entry in registered_envs()}
