"""Registration recall tables: python scripts/registration_recall.py [--pairs 50] [--output PATH_WITHOUT_SUFFIX].

Writes OUTPUT.md and OUTPUT.json (see ``infonav_gym.experiments.registration_recall``): every candidate
registration on the five seed sets, the one chosen, and the control-point strategies with it.
"""

import argparse
import json
import sys
from pathlib import Path

from infonav_gym.experiments.registration_recall import SEED_SETS, recall_markdown, registration_recall


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=50, help="seeds per set (the first of each set's 50)")
    parser.add_argument("--output", type=Path, default=Path("results/registration_recall"), help="path without suffix")
    args = parser.parse_args(argv)
    if not 1 <= args.pairs <= 50:
        parser.error(f"--pairs must be in 1..50, got {args.pairs}")
    result = registration_recall([seeds[: args.pairs] for seeds in SEED_SETS], progress=True)
    result["command"] = " ".join(["python scripts/registration_recall.py", *argv])
    args.output.parent.mkdir(parents=True, exist_ok=True)
    markdown = f"Made by `{result['command']}`.\n\n" + recall_markdown(result)
    args.output.with_suffix(".md").write_text(markdown)
    args.output.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    print(markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
