"""Re-run every committed evaluation in ``results/`` on its first seeds and compare episode for episode.

Usage: ``python scripts/check_committed_results.py [--episodes 5] [--rtol 1e-6] [--save DIR] [RESULT.json ...]``.
Exits 1 and names the file, agent, seed and metric when a number differs. What the agents decided is compared
exactly: the integers (episode lengths, counts) and the rates (success, failure: 0 or 1 per episode), which a
different decision changes. The other figures are sums of floating-point results, whose last digits differ
between CPUs and BLAS kernels (the committed files were written on other machines): they must agree to
``rtol`` (relative; 1e-6 by default), far above what rounding moves over an episode (about 1e-12 relative)
and far below what one different decision moves (percent). ``--rtol 0``: bit for bit. ``--save DIR`` writes
the fresh evaluations there, to compare a later run against them (``--rtol 0 DIR/*.json``). A file whose agents
need an extra that is not installed (``rllib:`` without Ray, ``benchmarl:`` without BenchMARL) or whose env's
dataset is absent is skipped, saying so.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import sys
from pathlib import Path

from infonav_gym.experiments.evaluation import evaluate
from infonav_gym.registry import env_entry, missing_dataset

RESULTS = Path(__file__).resolve().parent.parent / "results"
EXTRA_AGENTS = {"rllib:": ("ray", "distributed"), "benchmarl:": ("benchmarl", "marl")}  # agent prefix: module, extra


def evaluations(paths: list[Path]) -> list[Path]:
    """The given files, or every ``results/*.json`` written by ``infonav evaluate``."""
    return paths or [path for path in sorted(RESULTS.glob("*.json")) if "agents" in json.loads(path.read_text())]


def missing_extra(path: Path) -> str | None:
    """Why ``path``'s evaluation cannot run here (an ``rllib:`` agent without Ray, its env's dataset absent)."""
    committed = json.loads(path.read_text())
    for prefix, (module, extra) in EXTRA_AGENTS.items():
        if any(name.startswith(prefix) for name in committed["agents"]) and importlib.util.find_spec(module) is None:
            return f'its {prefix} agent needs {module} (pip install "infonav-gym[{extra}]")'
    return missing_dataset(committed["env_id"], **committed["env_kwargs"])


def exact_metrics(env_id: str) -> set[str]:
    """The names of ``env_id``'s rate metrics (``EpisodeMetric.proportion``): decisions, compared exactly."""
    return {metric.name for metric in env_entry(env_id).load().episode_metrics if metric.proportion}


def reproduced(old, new, exact: bool, rtol: float) -> bool:
    """Whether a fresh figure ``new`` reproduces the committed ``old``: exactly for integers and ``exact``
    figures, else to ``rtol``."""
    if new is None:
        return False
    if exact or isinstance(old, int):
        return new == old
    return math.isclose(new, old, rel_tol=rtol, abs_tol=rtol)


def differences(path: Path, episodes: int, rtol: float, save: Path | None = None) -> list[str]:
    """Every per-episode number of ``path`` (first ``episodes`` seeds) that a fresh evaluation does not reproduce."""
    committed = json.loads(path.read_text())
    exact = exact_metrics(committed["env_id"])
    seed = committed["seeds"][0]
    fresh = evaluate(committed["env_id"], list(committed["agents"]), episodes, seed, committed["env_kwargs"], False)
    if save is not None:
        save.mkdir(parents=True, exist_ok=True)
        (save / path.name).write_text(json.dumps(fresh, indent=2) + "\n")
    found = []
    for name, result in committed["agents"].items():
        for index, (old, new) in enumerate(zip(result["episodes"][:episodes], fresh["agents"][name]["episodes"])):
            for key, value in old.items():
                if not reproduced(value, new.get(key), key in exact, rtol):
                    found.append(
                        f"{path.name}: {name}, seed {seed + index}, {key}: committed {value}, now {new.get(key)}"
                    )
    return found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="*", type=Path)
    parser.add_argument("--episodes", type=int, default=5)
    parser.add_argument("--rtol", type=float, default=1e-6)
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
