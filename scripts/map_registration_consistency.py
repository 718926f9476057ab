"""The NEES of MapRegistration-v0's fused fixes: python scripts/map_registration_consistency.py [--registrations 1000]
[--agents everything,greedy,random] [--output PATH_WITHOUT_SUFFIX].

Writes OUTPUT.md, OUTPUT.json and OUTPUT.png (``infonav_gym.experiments.map_consistency``).
"""

import argparse
import json
import sys
from pathlib import Path

from infonav_gym.experiments.episodes import check_agent_name
from infonav_gym.experiments.map_consistency import (
    check_registrations,
    consistency_markdown,
    fused_nees,
    plot_nees,
    summary,
)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--registrations", type=int, default=1000, help="fused fixes per agent (default 1000)")
    parser.add_argument("--agents", default="everything,greedy,random", help="comma-separated agent names")
    parser.add_argument("--output", type=Path, default=Path("results/map_registration_consistency"))
    args = parser.parse_args(argv)
    agents = args.agents.split(",")
    try:
        check_registrations(args.registrations)
        for agent in agents:
            check_agent_name(agent)
    except ValueError as error:
        parser.error(str(error))
    runs = [fused_nees(agent, args.registrations, progress=True) for agent in agents]
    command = " ".join(["python scripts/map_registration_consistency.py", *argv])
    summaries = [summary(run) for run in runs]
    markdown = consistency_markdown(summaries, command)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    plot_nees(runs, args.output.with_suffix(".png"))
    args.output.with_suffix(".md").write_text(markdown)
    args.output.with_suffix(".json").write_text(
        json.dumps({"command": command, "summaries": summaries}, indent=1) + "\n"
    )
    print(markdown)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
