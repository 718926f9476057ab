"""What the benchmark steps at each vector size N (native vector envs under random valid actions, CartPoleVectorEnv,
VMAS ``navigation``), and memory per sub-env; a vector step counts N env-steps."""

from __future__ import annotations

import importlib
import importlib.util
import os
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from gymnasium.envs.classic_control.cartpole import CartPoleVectorEnv
from gymnasium.vector import AutoresetMode

from infonav_gym.registry import make_vector_env, registered_envs

DEFAULT_VECTOR_SIZES = (1, 16, 64, 256, 1024)
MAX_VECTOR_SIZE = 65_536  # sub-envs of one measured vector env
MEMORY_STEPS = 1000  # vector steps inside the measured peak: episodes enough for what copies build up as they go
MEMORY_SECONDS = 60.0  # ... or fewer: a memory run stops stepping after this (one step at least) [s]
VMAS_AGENTS = 4
VMAS_MAX_STEPS = 100  # VMAS navigation episode length [steps] (BenchMARL's); without it episodes rarely end
PROC_STATUS = Path("/proc/self/status")  # Linux: the current (VmRSS) and the peak (VmHWM) resident set size
PROC_CLEAR_REFS = Path("/proc/self/clear_refs")  # Linux: writing "5" resets the peak to the current size


@dataclass(frozen=True)
class VectorRun:
    """A vector env ready to time: ``start()`` resets it, each ``step()`` steps all ``num_envs`` copies once."""

    num_envs: int
    start: Callable[[], None]
    step: Callable[[], None]


def check_vector_sizes(sizes, where: str = "vector sizes") -> tuple[int, ...]:
    """``sizes`` as a tuple of ints, once checked to be integers from 1 to ``MAX_VECTOR_SIZE`` (``ValueError``)."""
    sizes = tuple(sizes)
    if not sizes:
        raise ValueError(f"{where}: expected at least one number of sub-envs, got none")
    for size in sizes:
        if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or not 1 <= size <= MAX_VECTOR_SIZE:
            raise ValueError(
                f"{where}: each number of sub-envs must be an integer from 1 to {MAX_VECTOR_SIZE}, "
                f"got {size!r} in {sizes}"
            )
    return tuple(int(size) for size in sizes)


def parse_vector_sizes(text: str, where: str = "--vector-sizes") -> tuple[int, ...]:
    """Comma-separated numbers of sub-envs, ``"1,16,256"`` -> ``(1, 16, 256)`` (``ValueError`` naming ``where``)."""
    sizes = []
    for part in text.split(","):
        try:
            sizes.append(int(part))
        except ValueError:
            raise ValueError(
                f"{where}: expected comma-separated integers >= 1 such as '1,16,256', got {part.strip()!r} in {text!r}"
            ) from None
    return check_vector_sizes(sizes, where)


def vector_env_ids() -> list[str]:
    """Every registered env with a native vector env, in registration order."""
    return [entry.id for entry in registered_envs() if entry.vector_entry_point is not None]


def random_valid_actions(masks: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One action per row of ``masks`` (..., K), uniform over its ``True`` entries (each row needs one)."""
    scores = np.where(masks, rng.random(masks.shape), -1.0)
    return scores.argmax(axis=-1)


def vector_env_run(env_id: str, num_envs: int, seed: int, num_threads: int = 1) -> VectorRun:
    """``env_id``'s native vector env with ``num_envs`` copies on ``num_threads`` under random valid actions, in
    ``NEXT_STEP`` autoreset as ``CartPoleVectorEnv``."""
    env = make_vector_env(env_id, num_envs, num_threads=num_threads, autoreset_mode=AutoresetMode.NEXT_STEP)
    rng = np.random.default_rng(seed)
    return VectorRun(
        num_envs,
        start=lambda: env.reset(seed=seed),
        step=lambda: env.step(random_valid_actions(env.action_masks(), rng)),
    )


def cartpole_vector_run(num_envs: int, seed: int) -> VectorRun:
    """Gymnasium's ``CartPoleVectorEnv`` with ``num_envs`` copies under its seeded ``action_space.sample()``."""
    env = CartPoleVectorEnv(num_envs=num_envs)
    env.action_space.seed(seed)
    return VectorRun(num_envs, start=lambda: env.reset(seed=seed), step=lambda: env.step(env.action_space.sample()))


def vmas_missing() -> str | None:
    """Why the VMAS figures are absent (``vmas`` does not import), or None when it imports."""
    try:
        importlib.import_module("vmas")
    except ImportError as error:
        return f"VMAS figures absent: vmas does not import ({error}); pip install 'infonav-gym[bench]'"
    return None


def vmas_navigation_run(num_envs: int, seed: int) -> VectorRun:
    """VMAS ``navigation`` (``VMAS_AGENTS`` agents, CPU, one torch thread) under uniform random forces."""
    from agents.base import torch_threads

    vmas, torch = importlib.import_module("vmas"), importlib.import_module("torch")
    env = vmas.make_env(
        "navigation", num_envs=num_envs, device="cpu", n_agents=VMAS_AGENTS, max_steps=VMAS_MAX_STEPS, seed=seed
    )
    rng = np.random.default_rng(seed)
    spaces = [env.action_space[agent] for agent in range(VMAS_AGENTS)]

    def step() -> None:
        with torch_threads(1):
            forces = [rng.uniform(space.low, space.high, (num_envs, *space.shape)) for space in spaces]
            actions = [torch.from_numpy(force.astype(np.float32)) for force in forces]
            dones = env.step(actions)[2]
            for index in torch.nonzero(dones).flatten().tolist():
                env.reset_at(index, return_observations=False)

    def start() -> None:
        with torch_threads(1):
            env.reset(seed=seed, return_observations=False)

    return VectorRun(num_envs, start, step)


def torchrl_missing() -> str | None:
    """Why the TorchRL figures are absent (torchrl is not installed), or None."""
    if importlib.util.find_spec("torchrl") is None:
        return 'TorchRL figures absent: torchrl is not installed; pip install "infonav-gym[marl]"'
    return None


def torchrl_env_run(env_id: str, num_envs: int, seed: int) -> VectorRun:
    """``env_id`` as the suite's TorchRL env (``agents.torchrl_env``) with ``num_envs`` copies under random valid
    actions, restarted by TorchRL's ``step_and_maybe_reset`` as its collectors do."""
    import torch

    from agents.torchrl_env import GROUP, InfonavTorchEnv

    env = InfonavTorchEnv(env_id, num_envs, seed=seed)
    rng = np.random.default_rng(seed)
    action, mask = ((GROUP, key) if env.team else key for key in ("action", "action_mask"))
    current = {}

    def start() -> None:
        current["td"] = env.reset()

    def step() -> None:
        td = current["td"]
        td.set(action, torch.from_numpy(random_valid_actions(td.get(mask).numpy(), rng)))
        current["td"] = env.step_and_maybe_reset(td)[1]

    return VectorRun(num_envs, start, step)


def _status_kb(field: str) -> int:
    """A memory figure [kB] of this process from ``/proc/self/status`` (Linux): ``VmRSS`` now, ``VmHWM`` its peak."""
    for line in PROC_STATUS.read_text().splitlines():
        if line.startswith(f"{field}:"):
            return int(line.split()[1])
    raise ValueError(f"{PROC_STATUS} has no {field} line")


def _run_for(run: VectorRun, steps: int, seconds: float) -> None:
    """Start ``run``, then step it ``steps`` times, or fewer (one at least) once ``seconds`` have passed."""
    run.start()
    deadline = time.perf_counter() + seconds
    for _ in range(steps):
        run.step()
        if time.perf_counter() >= deadline:
            return


def peak_rss_growth_kb_per_env(
    env_id: str, num_envs: int, steps: int, seed: int, seconds: float = MEMORY_SECONDS
) -> float:
    """In this process: peak RSS growth [kB] per copy of building, resetting and stepping ``num_envs`` copies, after a
    warmed-up 1-copy run and a reset of the peak (``/proc/self/clear_refs``)."""
    warm_up = vector_env_run(env_id, 1, seed)  # kept through the measurement
    _run_for(warm_up, steps, seconds)
    PROC_CLEAR_REFS.write_text("5")  # Linux: "5" resets the peak RSS to the current RSS
    before = _status_kb("VmRSS")
    _run_for(vector_env_run(env_id, num_envs, seed), steps, seconds)
    return (_status_kb("VmHWM") - before) / num_envs


def kb_per_env(
    env_id: str, num_envs: int, steps: int = MEMORY_STEPS, seed: int = 0, seconds: float = MEMORY_SECONDS
) -> float:
    """Memory per sub-env [kB] of ``env_id``'s vector env: ``peak_rss_growth_kb_per_env`` in a fresh subprocess, which
    imports only ``infonav_gym`` (``RuntimeError`` with its error output if it fails)."""
    code = (
        "from infonav_gym.experiments.vector_timing import peak_rss_growth_kb_per_env; "
        f"print(peak_rss_growth_kb_per_env({env_id!r}, {num_envs}, {steps}, {seed}, {seconds!r}))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if done.returncode:
        raise RuntimeError(f"memory of {env_id} at N={num_envs}: the measuring subprocess failed:\n{done.stderr}")
    return float(done.stdout.split()[-1])


def memory_missing() -> str | None:
    """Why the memory figures are absent (not Linux: no writable ``/proc/self/clear_refs``), or None if they can be."""
    if PROC_STATUS.exists() and os.access(PROC_CLEAR_REFS, os.W_OK):
        return None
    return f"memory figures absent: they need Linux's {PROC_STATUS} and a writable {PROC_CLEAR_REFS}"
