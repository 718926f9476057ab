"""Where a cold start goes: python scripts/cold_start_breakdown.py [--top N] [--json] [--together] [ENV_ID ...].

Each env runs in a fresh process (all in one with ``--together``) with an empty numba cache, as ``startup_timing``:
the seconds of importing numba and the package, making the env (its modules imported), its first reset and step, of
LLVM, and each kernel compile: its own seconds (without the kernels it compiles in turn), its phase and caller, and
how many argument types the kernel compiled for.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

PROFILE_SCRIPT = """
import json, sys, time

started = time.perf_counter()
from numba.core import event

seconds, compiles, stack, phase = {"numba_import": time.perf_counter() - started}, [], [], ["import"]

def name_of(event_):
    function = event_.data["dispatcher"].py_func
    return f"{function.__module__}.{function.__qualname__}"

class Compiles(event.Listener):
    def on_start(self, event_):
        stack.append([time.perf_counter(), 0.0, name_of(event_)])

    def on_end(self, event_):
        start, nested, name = stack.pop()
        seconds = time.perf_counter() - start
        if stack:
            stack[-1][1] += seconds
        compiles.append(
            {"kernel": name, "args": str(event_.data["args"]), "phase": phase[0], "self_s": seconds - nested,
             "caller": stack[-1][2] if stack else None}
        )

event.register("numba:compile", Compiles())
llvm = event.TimingListener()
event.register("numba:llvm_lock", llvm)

def timed(name, action):
    phase[0] = name
    start = time.perf_counter()
    result = action()
    seconds[name] = seconds.get(name, 0.0) + time.perf_counter() - start
    return result

import numpy as np
timed("import", lambda: __import__("infonav_gym"))
from infonav_gym import make_env
from infonav_gym.registry import PARALLEL, api_of

for env_id in sys.argv[1:]:
    env = timed("make", lambda: make_env(env_id))
    _, info = timed("reset", lambda: env.reset(seed=0))
    if api_of(env_id) == PARALLEL:
        action = {agent: int(np.argmax(info[agent]["action_mask"])) for agent in env.agents}
    else:
        action = int(np.argmax(info["action_mask"]))
    timed("step", lambda: env.step(action))
seconds["total"] = time.perf_counter() - started
seconds["llvm"] = llvm.duration if llvm.done else 0.0
print(json.dumps({"seconds": seconds, "compiles": compiles}))
"""


def breakdown(env_ids: list[str]) -> dict:
    """The profile of one process's cold start of ``env_ids``, with ``wall_s``: the whole process's wall seconds."""
    with tempfile.TemporaryDirectory(prefix="infonav-numba-cache-") as cache_dir:
        start = time.perf_counter()
        result = subprocess.run(
            [sys.executable, "-c", PROFILE_SCRIPT, *env_ids],
            capture_output=True,
            text=True,
            env={**os.environ, "NUMBA_CACHE_DIR": cache_dir},
            check=True,
        )
        wall_s = time.perf_counter() - start
    return {"env": " + ".join(env_ids), "wall_s": wall_s, **json.loads(result.stdout.splitlines()[-1])}


def report(profile: dict, top: int) -> str:
    """A few lines: the phases' seconds, the compile total per phase, and the ``top`` kernels by own compile time."""
    seconds, compiles = profile["seconds"], profile["compiles"]
    signatures: dict[str, set] = {}
    for compile_ in compiles:
        signatures.setdefault(compile_["kernel"], set()).add(compile_["args"])
    phases = ", ".join(f"{name} {value:.2f}" for name, value in seconds.items())
    per_phase = {phase: sum(c["self_s"] for c in compiles if c["phase"] == phase) for phase in seconds}
    lines = [
        f"{profile['env']}: wall {profile['wall_s']:.2f} s ({phases}); {len(compiles)} compiles of "
        f"{len(signatures)} kernels, {sum(per_phase.values()):.2f} s: "
        + ", ".join(f"{phase} {value:.2f}" for phase, value in per_phase.items() if value)
    ]
    for compile_ in sorted(compiles, key=lambda c: -c["self_s"])[:top]:
        count = len(signatures[compile_["kernel"]])
        lines.append(
            f"  {compile_['self_s']:6.2f} s  {compile_['phase']:6}  {compile_['kernel']}"
            + (f"  ({count} signatures)" if count > 1 else "")
        )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("env_ids", nargs="*")
    parser.add_argument("--top", type=int, default=8)
    parser.add_argument("--json", action="store_true", help="print every compile, as JSON")
    parser.add_argument("--together", action="store_true", help="every env in one process (cold_start_all_envs_s)")
    arguments = parser.parse_args()
    from infonav_gym.registry import available_envs

    env_ids = arguments.env_ids or [entry.id for entry in available_envs()]
    profiles = [breakdown(env_ids)] if arguments.together else [breakdown([env_id]) for env_id in env_ids]
    print(json.dumps(profiles, indent=1) if arguments.json else "\n".join(report(p, arguments.top) for p in profiles))


if __name__ == "__main__":
    main()
