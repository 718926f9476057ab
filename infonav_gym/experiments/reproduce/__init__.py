"""Regenerate the paper's figures from the environments (``infonav reproduce``)."""

import json
from pathlib import Path

from infonav_gym.experiments.paths import OutputWriteError, check_output_dir, write_failure
from infonav_gym.experiments.reproduce import fig3, fig5, fig6

DEFAULT_OUTPUT_DIR = Path("results")  # relative to the working directory
# name -> its module: figures(seed, seeds, progress) -> (JSON-ready figures, the function drawing them into a PNG),
# table(result) -> the figures as text, SEEDS_COUNT: what ``n_seeds`` counts, for its error
FIGURES = {module.__name__.rpartition(".")[2]: module for module in (fig3, fig5, fig6)}


def reproduce(figure: str, output_dir, seed: int = 0, n_seeds: int = 20, progress: bool = True, command: str = ""):
    """Run ``figure`` (one of ``FIGURES``), write ``output_dir/FIGURE.png`` and ``FIGURE.json``; return its content.
    ``ValueError`` for ``n_seeds < 1`` or an unwritable ``output_dir``; ``OutputWriteError`` (carrying the result and
    the files written) when a file cannot be written."""
    paper_figure = FIGURES[figure]
    if n_seeds < 1:
        raise ValueError(f"n_seeds ({paper_figure.SEEDS_COUNT}) must be >= 1, got {n_seeds}")
    output_dir = check_output_dir(output_dir, "output directory")
    try:
        output_dir.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ValueError(f"output directory {output_dir}: {error.strerror or error}") from None
    png, json_path = output_dir / f"{figure}.png", output_dir / f"{figure}.json"
    figures, plot = paper_figure.figures(seed, range(seed, seed + n_seeds), progress)
    result = {"command": command, **figures, "files": []}
    try:
        plot(png)
        result["files"] += [str(png), str(json_path)]  # the JSON lists itself
        json_path.write_text(json.dumps(result, indent=1) + "\n")
    except OSError as error:
        result["files"] = result["files"][:1]
        raise OutputWriteError(write_failure(f"{png.stem}'s files", error), result) from None
    return result


def printed_table(figure: str, result: dict) -> str:
    """``figure``'s table of ``result`` and, last, the files it wrote."""
    files = f"wrote {', '.join(result['files'])}" if result["files"] else "wrote no files"
    return f"{FIGURES[figure].table(result)}\n{files}"
