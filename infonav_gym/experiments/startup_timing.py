"""How long a user waits before the first step: a fresh process imports the suite, makes every registered env,
resets it and steps it once.

``cold_start_s``: with an empty numba cache (``NUMBA_CACHE_DIR`` a new directory), so every compiled kernel is
compiled; ``warm_start_s``: the same again with the cache the cold run filled. Both are whole-process wall times,
interpreter start included, as a user sees them.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

FIRST_STEP_SCRIPT = """
import numpy as np
from infonav_gym import make_env, registered_envs
from infonav_gym.registry import PARALLEL

for entry in registered_envs():
    env = make_env(entry.id)
    if entry.api == PARALLEL:
        _, infos = env.reset(seed=0)
        env.step({agent: int(np.argmax(infos[agent]["action_mask"])) for agent in env.agents})
    else:
        _, info = env.reset(seed=0)
        env.step(int(np.argmax(info["action_mask"])))
    env.close()
"""


def first_step_seconds(cache_dir: str) -> float:
    """Wall seconds of a fresh Python process running ``FIRST_STEP_SCRIPT`` with numba's cache in ``cache_dir``.

    Raises:
        RuntimeError: if the process fails (its stderr's last line quoted).
    """
    environment = {**os.environ, "NUMBA_CACHE_DIR": cache_dir}
    start = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-c", FIRST_STEP_SCRIPT], capture_output=True, text=True, env=environment, check=False
    )
    seconds = time.perf_counter() - start
    if result.returncode != 0:
        last_line = (result.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"the first-step process failed (exit {result.returncode}): {last_line}")
    return seconds


def startup_figures() -> dict:
    """``{"cold_start_s", "warm_start_s"}``: the first-step process with an empty numba cache, then with it filled."""
    with tempfile.TemporaryDirectory(prefix="infonav-numba-cache-") as cache_dir:
        cold = first_step_seconds(cache_dir)
        warm = first_step_seconds(cache_dir)
    return {"cold_start_s": cold, "warm_start_s": warm}
