"""Regenerate a figure of the paper: python scripts/reproduce_paper.py fig3 [--output-dir DIR] [--seeds N] [--json]."""

import sys

from infonav_gym.cli import main

if __name__ == "__main__":
    raise SystemExit(main(["reproduce", *sys.argv[1:]]))
