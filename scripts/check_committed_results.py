"""Re-run every committed evaluation in ``results/`` on its first seeds and compare episode for episode.

Usage: ``python scripts/check_committed_results.py [--episodes 5] [--rtol 1e-9] [--save DIR] [RESULT.json ...]``.
Exits 1 and names the file, agent, seed and metric when a number differs by more than ``rtol``
(``--rtol 0``: bit for bit; the committed files were written on other machines, whose BLAS may
round the last digit differently). ``--save DIR`` writes the fresh evaluations there, to compare
a later run against them bit for bit (``--rtol 0 DIR/*.json``). A file whose agents need an extra that
is not installed (``rllib:`` without Ray) is skipped, saying so.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
from pathlib import Path

from infonav_gym.experiments.evaluation import evaluate

RESULTS = Path(__file__).resolve().parent.parent / "results"


def evaluations(paths: list[Path]) -> list[Path]:
    """The given files, or every ``results/*.json`` written by ``infonav evaluate``."""
    return paths or [path for path in sorted(RESULTS.glob("*.json")) if "agents" in json.loads(path.read_text())]


def missing_extra(path: Path) -> str | None:
    """Why ``path``'s agents cannot run here (an ``rllib:`` agent without Ray), or None."""
    agents = json.loads(path.read_text())["agents"]
    if any(name.startswith("rllib:") for name in agents) and importlib.util.find_spec("ray") is None:
        return 'its rllib: agent needs Ray (pip install "infonav-gym[distributed]")'
    return None


def differences(path: Path, episodes: int, rtol: float, save: Path | None = None) -> list[str]:
    """Every per-episode number of ``path`` (first ``episodes`` seeds) that a fresh evaluation does not reproduce."""
    committed = json.loads(path.read_text())
    seed = committed["seeds"][0]
    fresh = evaluate(committed["env_id"], list(committed["agents"]), episodes, seed, committed["env_kwargs"], False)
    if save is not None:
        save.mkdir(parents=True, exist_ok=True)
        (save / path.name).write_text(json.dumps(fresh, indent=2) + "\n")
    found = []
    for name, result in committed["agents"].items():
        for index, (old, new) in enumerate(zip(result["episodes"][:episodes], fresh["agents"][name]["episodes"])):
            for key, value in old.items():
                if key not in new or not math.isclose(new[key], value, rel_tol=rtol, abs_tol=rtol):
                    found.append(
                        f"{path.name}: {name}, seed {seed + index}, {key}: committed {value}, now {new.get(key)}"
                    )
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="*", type=Path)
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--rtol", type=float, default=1e-9)
    parser.add_argument("--save", type=Path)
    args = parser.parse_args(argv)
    failures = []
    for path in evaluations(args.files):
        if reason := missing_extra(path):
            print(f"{path.name}: skipped, {reason}", flush=True)
            continue
        found = differences(path, args.episodes, args.rtol, args.save)
        print(f"{path.name}: {'reproduced' if not found else f'{len(found)} differences'}", flush=True)
        failures += found
    print("\n".join(failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
