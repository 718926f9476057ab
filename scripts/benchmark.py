"""Speed goals (``infonav benchmark``): python scripts/benchmark.py [--json] [--rounds N] [--seconds S]."""

import sys

from infonav_gym.experiments.cli import main

if __name__ == "__main__":
    raise SystemExit(main(["benchmark", *sys.argv[1:]]))
