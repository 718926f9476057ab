"""A SHA-256 of every registered env's outputs: what a refactor must leave unchanged.

Each env is played through its single view (the Gymnasium env, or the PettingZoo parallel env) and its native
vector env at ``COPIES`` copies in each autoreset mode, for ``STEPS`` steps from seed 0 (episodes that end are
reset with the next seed), with actions drawn uniformly over the valid ones from a fixed seed. Observations,
rewards, terminations, truncations and infos all enter the hash (but ``WALL_CLOCK_KEYS``).

Usage: ``python scripts/env_fingerprints.py [--save FILE] [--compare FILE]``. ``--compare`` exits 1 naming every
view of FILE whose hash differs (and names, without failing, the views FILE lacks: envs registered since). Every
env that can be made here (``available_envs``) is played. Run both on the same machine (before and after a change):
the last digits of floating-point outputs may differ between CPUs.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from infonav_gym.experiments.vector_timing import random_valid_actions
from infonav_gym.registry import PARALLEL, api_of, available_envs, make_env, make_vector_env

STEPS = 60
COPIES = 3
AUTORESET_MODES = ("next_step", "same_step")
WALL_CLOCK_KEYS = {"icp_time_s"}  # info keys that measure the machine's time, not the env's: left out


def digest(value, hasher) -> None:
    """Feed ``value`` (arrays, numbers, strings, None and dicts / sequences of them) into ``hasher``, keys sorted."""
    if isinstance(value, dict):
        for key in sorted(set(value) - WALL_CLOCK_KEYS, key=str):
            hasher.update(repr(key).encode())
            digest(value[key], hasher)
    elif isinstance(value, list | tuple):
        hasher.update(f"[{len(value)}".encode())
        for item in value:
            digest(item, hasher)
    elif value is None or isinstance(value, str):
        hasher.update(repr(value).encode())
    else:
        array = np.ascontiguousarray(value)
        hasher.update(f"{array.dtype.str}{array.shape}".encode())
        if array.dtype == object:  # its bytes are addresses: hash what it holds
            digest(array.ravel().tolist(), hasher)
        else:
            hasher.update(array.tobytes())


def single_view(env_id: str) -> str:
    """The hash of ``env_id``'s single view (N = 1: Gymnasium, or PettingZoo parallel) over ``STEPS`` steps."""
    env, rng, hasher, seed = make_env(env_id), np.random.default_rng(0), hashlib.sha256(), 0
    team = api_of(env_id) == PARALLEL
    output = env.reset(seed=seed)
    digest(output, hasher)
    for _ in range(STEPS):
        infos = output[-1]
        if team:
            actions = {agent: int(random_valid_actions(infos[agent]["action_mask"] > 0, rng)) for agent in env.agents}
        else:
            actions = int(random_valid_actions(infos["action_mask"] > 0, rng))
        output = env.step(actions)
        digest(output, hasher)
        if (not env.agents) if team else (output[2] or output[3]):
            seed += 1
            output = env.reset(seed=seed)
            digest(output, hasher)
    env.close()
    return hasher.hexdigest()


def vector_view(env_id: str, autoreset_mode: str) -> str:
    """The hash of ``env_id``'s native vector env, ``COPIES`` copies in ``autoreset_mode``, over ``STEPS`` steps."""
    env, rng, hasher = (
        make_vector_env(env_id, COPIES, autoreset_mode=autoreset_mode),
        np.random.default_rng(0),
        hashlib.sha256(),
    )
    digest(env.reset(seed=0), hasher)
    for _ in range(STEPS):
        digest(env.step(random_valid_actions(env.action_masks(), rng)), hasher)
    env.close()
    return hasher.hexdigest()


def fingerprints() -> dict[str, str]:
    """``{"ENV_ID single" | "ENV_ID vector MODE": sha256}`` of every registered env."""
    result = {}
    for entry in available_envs():
        result[f"{entry.id} single"] = single_view(entry.id)
        if entry.vector_entry_point is not None:
            for mode in AUTORESET_MODES:
                result[f"{entry.id} vector {mode}"] = vector_view(entry.id, mode)
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--save", type=Path, help="write the fingerprints to this JSON file")
    parser.add_argument("--compare", type=Path, help="compare with the fingerprints in this JSON file")
    args = parser.parse_args(argv)
    result = fingerprints()
    print(json.dumps(result, indent=2))
    if args.save:
        args.save.write_text(json.dumps(result, indent=2) + "\n")
    if args.compare:
        before = json.loads(args.compare.read_text())
        changed = sorted(view for view in before if before[view] != result.get(view))
        for view in changed:
            print(f"changed: {view}", file=sys.stderr)
        for view in sorted(result.keys() - before.keys()):  # an env registered since: nothing to compare
            print(f"new: {view}", file=sys.stderr)
        return 1 if changed else 0
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
