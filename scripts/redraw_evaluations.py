"""Retitle every committed evaluation's metrics as the envs declare them now (with their units) and redraw its plot:
the JSON's titles, the Markdown table and the PNG; no episode is played again, no number or config changes.

Usage: ``python scripts/redraw_evaluations.py [RESULT.json ...]`` (default: every ``results/*.json`` that
``infonav evaluate`` wrote).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from infonav_gym.experiments.evaluation_files import markdown_table, plot_results
from infonav_gym.registry import env_entry

RESULTS = Path(__file__).resolve().parent.parent / "results"


def redraw(path: Path) -> list[Path]:
    """``path`` and its ``.md`` with the metrics retitled, and its ``.png`` redrawn; the paths written.

    Raises:
        ValueError: when the ``.md`` does not hold the table its JSON gives (written by other code): nothing written.
    """
    results = json.loads(path.read_text())
    declared = {metric.name: metric.title for metric in env_entry(results["env_id"]).load().episode_metrics}
    retitled = {**results, "metrics": {key: declared.get(key, title) for key, title in results["metrics"].items()}}
    markdown = path.with_suffix(".md")
    text, table = markdown.read_text(), markdown_table(results)
    if table not in text:
        raise ValueError(f"{markdown} does not hold the table of {path}: regenerate it with its command")
    markdown.write_text(text.replace(table, markdown_table(retitled)))
    path.write_text(json.dumps(retitled, indent=2) + "\n")
    return [path, markdown, plot_results(retitled, path.with_suffix(".png"))]


def main(paths: list[str]) -> None:
    for path in [Path(path) for path in paths] or sorted(RESULTS.glob("*.json")):
        if "agents" in json.loads(path.read_text()):
            print(f"wrote {', '.join(str(written) for written in redraw(path))}")


if __name__ == "__main__":
    main(sys.argv[1:])
