"""Regenerate the paper's figures: python scripts/reproduce_paper.py [FIGURE] [--output-dir DIR] [--seeds N] [--json].

FIGURE is one of ``infonav_gym.experiments.reproduce.FIGURES``; without one, all of them are made in turn
with the same options (with --json, one JSON object per line).
"""

import sys

from infonav_gym.experiments.cli import main
from infonav_gym.experiments.reproduce import FIGURES


def reproduce_all(argv: list[str]) -> int:
    """``infonav reproduce`` for the figure named first in ``argv``, or for every figure if none is named."""
    if argv and not argv[0].startswith("-"):
        return main(["reproduce", *argv])
    for figure in FIGURES:
        status = main(["reproduce", figure, *argv])
        if status:
            return status
    return 0


if __name__ == "__main__":
    raise SystemExit(reproduce_all(sys.argv[1:]))
