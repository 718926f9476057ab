"""Regenerate the paper's figures from the environments (``infonav reproduce``)."""

import json
from collections.abc import Callable
from pathlib import Path

from infonav_gym.experiments.paths import OutputWriteError, check_output_dir, write_failure

FIGURES = ("fig3", "fig5", "fig6")
DEFAULT_OUTPUT_DIR = Path("results")  # relative to the working directory


def paper_label(agent: str) -> str:
    """The paper's name of a robot, numbered from 1: ``robot_0`` -> ``#1``."""
    return f"#{int(agent.rpartition('_')[2]) + 1}"


def figure_paths(output_dir, figure: str, n_seeds: int, counted: str) -> tuple[Path, Path]:
    """Check ``n_seeds`` (``counted``: what the seeds count, for the error) and ``output_dir``, create it;
    return the figure's PNG and JSON paths in it.

    Raises:
        ValueError: for ``n_seeds < 1``, or an ``output_dir`` that cannot be a writable directory.
    """
    if n_seeds < 1:
        raise ValueError(f"n_seeds ({counted}) must be >= 1, got {n_seeds}")
    output_dir = check_output_dir(output_dir, "output directory")
    try:
        output_dir.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ValueError(f"output directory {output_dir}: {error.strerror or error}") from None
    return output_dir / f"{figure}.png", output_dir / f"{figure}.json"


def write_result(result: dict, png: Path, json_path: Path, plot: Callable[[Path], object]) -> dict:
    """Draw ``plot(png)``, record the two files in ``result``, write it as ``json_path`` and return it.

    Raises:
        OutputWriteError: when a file cannot be written; it carries ``result`` (with the files that
            were written), so the computed figures are not lost.
    """
    result["files"] = []
    try:
        plot(png)
        result["files"].append(str(png))
        result["files"].append(str(json_path))
        json_path.write_text(json.dumps(result, indent=1) + "\n")
    except OSError as error:
        result["files"] = result["files"][:1]
        raise OutputWriteError(write_failure(f"{png.stem}'s files", error), result) from None
    return result


def files_line(result: dict) -> str:
    """The last line of a figure's table: the files it wrote."""
    return f"wrote {', '.join(result['files'])}" if result["files"] else "wrote no files"
