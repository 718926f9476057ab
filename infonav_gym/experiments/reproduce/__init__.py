"""Regenerate the paper's figures from the environments (``infonav reproduce``)."""

import json
from pathlib import Path

FIGURES = ("fig3", "fig5", "fig6")


def paper_label(agent: str) -> str:
    """The paper's name of a robot, numbered from 1: ``robot_0`` -> ``#1``."""
    return f"#{int(agent.rpartition('_')[2]) + 1}"


def figure_paths(output_dir, figure: str, n_seeds: int, counted: str) -> tuple[Path, Path]:
    """Check ``n_seeds`` (``counted``: what the seeds count, for the error), create ``output_dir``;
    return the figure's PNG and JSON paths in it."""
    if n_seeds < 1:
        raise ValueError(f"n_seeds ({counted}) must be >= 1, got {n_seeds}")
    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    return output_dir / f"{figure}.png", output_dir / f"{figure}.json"


def write_result(result: dict, png: Path, json_path: Path) -> dict:
    """Record the two files in ``result``, write it as ``json_path`` and return it."""
    result["files"] = [str(png), str(json_path)]
    json_path.write_text(json.dumps(result, indent=1) + "\n")
    return result
