"""How long a user waits before the first step, in fresh processes: ``cold_start_s`` (empty numba cache),
``warm_start_s`` (filled), each the slowest env's, and ``cold_start_all_envs_s`` (every env in one process)."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

FIRST_STEP_SCRIPT = """
import sys

import numpy as np
from infonav_gym import make_env
from infonav_gym.registry import PARALLEL, api_of

for env_id in sys.argv[1:]:
    env = make_env(env_id)
    if api_of(env_id) == PARALLEL:
        _, infos = env.reset(seed=0)
        env.step({agent: int(np.argmax(infos[agent]["action_mask"])) for agent in env.agents})
    else:
        _, info = env.reset(seed=0)
        env.step(int(np.argmax(info["action_mask"])))
    env.close()
"""


def first_step_seconds(cache_dir: str, env_ids: list[str]) -> float:
    """Wall seconds of a fresh process running ``FIRST_STEP_SCRIPT`` on ``env_ids``, numba's cache in ``cache_dir``
    (``RuntimeError`` quoting its stderr's last line if it fails)."""
    environment = {**os.environ, "NUMBA_CACHE_DIR": cache_dir}
    start = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-c", FIRST_STEP_SCRIPT, *env_ids], capture_output=True, text=True, env=environment
    )
    seconds = time.perf_counter() - start
    if result.returncode != 0:
        last_line = (result.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"the first-step process failed (exit {result.returncode}): {last_line}")
    return seconds


def startup_figures(env_ids: list[str]) -> dict:
    """``{"cold_start_s", "warm_start_s", "cold_start_all_envs_s"}`` of ``env_ids`` (see the module)."""
    cold, warm = [], []
    for env_id in env_ids:
        with tempfile.TemporaryDirectory(prefix="infonav-numba-cache-") as cache_dir:
            cold.append(first_step_seconds(cache_dir, [env_id]))
            warm.append(first_step_seconds(cache_dir, [env_id]))
    with tempfile.TemporaryDirectory(prefix="infonav-numba-cache-") as cache_dir:
        cold_all = first_step_seconds(cache_dir, env_ids)
    return {"cold_start_s": max(cold), "warm_start_s": max(warm), "cold_start_all_envs_s": cold_all}
