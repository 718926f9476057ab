"""Registration recall tables: python scripts/registration_recall.py [--pairs 50] [--budgets 0.05,0.1,0.25,0.5]
[--output PATH_WITHOUT_SUFFIX].

Writes OUTPUT.md, OUTPUT.json and OUTPUT.png (see ``infonav_gym.experiments.registration_recall``): every
candidate registration on the five seed sets, the one chosen, and every control-point selector with it at each
budget (a fraction of the returns), against all returns; the plot of median error against budget and time.
"""

import argparse
import json
import sys
from pathlib import Path

from infonav_gym.experiments.registration_recall import (
    BUDGETS,
    SEED_SETS,
    check_budgets,
    plot_comparison,
    recall_markdown,
    registration_recall,
)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=50, help="seeds per set (the first of each set's 50)")
    parser.add_argument(
        "--budgets",
        default=",".join(f"{budget:g}" for budget in BUDGETS),
        help="control points as comma-separated fractions of the returns, each in (0, 1]",
    )
    parser.add_argument("--output", type=Path, default=Path("results/registration_recall"), help="path without suffix")
    args = parser.parse_args(argv)
    if not 1 <= args.pairs <= 50:
        parser.error(f"--pairs must be in 1..50, got {args.pairs}")
    try:
        budgets = check_budgets(float(budget) for budget in args.budgets.split(","))
    except ValueError as error:
        parser.error(f"--budgets {args.budgets!r}: {error}")
    result = registration_recall([seeds[: args.pairs] for seeds in SEED_SETS], budgets, progress=True)
    result["command"] = " ".join(["python scripts/registration_recall.py", *argv])
    markdown = f"Made by `{result['command']}`.\n\n" + recall_markdown(result)
    plot_comparison(result["control_points"], args.output.with_suffix(".png"))
    args.output.with_suffix(".md").write_text(markdown)
    args.output.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    print(markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
