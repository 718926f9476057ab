"""Shared test setup.

- pygame must never open a real window in tests: select SDL's dummy video driver
  before anything imports pygame.
- ``$INFONAV_MRCLAM_DATASET`` names a synthetic MRCLAM directory (``mrclam_exact``), for the MRCLAM env.
- ``spawned_reset_observation`` runs in a *spawned* child process. It lives here,
  not in ``test_envs.py``, because unpickling it in the child imports its module:
  this module deliberately does not import ``infonav_gym``, so the child proves that
  ``gym.make("infonav_gym:...")`` imports and registers the package by itself.
"""

import contextlib
import os
import socket

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import atexit  # noqa: E402
import shutil  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from mrclam_exact import write_dataset  # noqa: E402

# infonav/MRCLAMLocalization-v0 reads a real dataset a fresh clone does not have: every test (and each process it
# starts) plays the synthetic one, 120 s of it, the landmarks seen within 1 rad of the heading; tests of the real
# Dataset 6 name its directory themselves.
_synthetic_mrclam = Path(tempfile.mkdtemp(prefix="infonav-mrclam-"))
atexit.register(shutil.rmtree, _synthetic_mrclam, ignore_errors=True)
_synthetic_mrclam = write_dataset(_synthetic_mrclam / "synthetic", duration_s=120.0, field_of_view_rad=2.0)
os.environ["INFONAV_MRCLAM_DATASET"] = str(_synthetic_mrclam)


def pytest_configure(config):
    config.addinivalue_line("markers", "render: needs infonav_gym.rendering (pygame)")


def spawned_reset_observation(seed: int = 3, env_id: str = "infonav/LandmarkSelection-v0") -> tuple[bool, list[float]]:
    """In a fresh interpreter: make the env through the ``module:`` prefix, reset, return the observation.

    Also returns whether ``infonav_gym`` had already been imported before ``gym.make``.
    """
    imported_before = "infonav_gym" in sys.modules
    import gymnasium as gym

    env = gym.make(f"infonav_gym:{env_id}")
    observation, _ = env.reset(seed=seed)
    env.close()
    return imported_before, observation.tolist()


@pytest.fixture
def spawned_reset():
    return spawned_reset_observation


def numerical_jacobian(function, point, step=1e-7):
    """Central differences of ``function`` (vector -> vector) at ``point``, angle differences wrapped.

    (Wrapped here rather than with ``infonav_gym``'s ``wrap_angle``: this module must not import the package.)
    """
    point = np.asarray(point, dtype=float)
    columns = []
    for i in range(point.size):
        offset = np.zeros_like(point)
        offset[i] = step
        difference = np.asarray(function(point + offset)) - np.asarray(function(point - offset))
        wrapped = (difference + np.pi) % (2 * np.pi) - np.pi  # angles across the branch cut
        columns.append(wrapped / (2 * step))
    return np.stack(columns, axis=-1)


def assert_identical(a, b, where: str = "value") -> None:
    """Exact (bit-for-bit) equality of nested dicts / sequences / arrays / scalars, types included."""
    assert type(a) is type(b), f"{where}: type {type(a).__name__} != {type(b).__name__}"
    if isinstance(a, dict):
        assert a.keys() == b.keys(), f"{where}: keys {sorted(a)} != {sorted(b)}"
        for key in a:
            assert_identical(a[key], b[key], f"{where}[{key!r}]")
    elif isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape, f"{where}: {a.dtype}{a.shape} != {b.dtype}{b.shape}"
        assert np.array_equal(a, b), f"{where}: arrays differ\n{a}\n{b}"
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b), f"{where}: lengths {len(a)} != {len(b)}"
        for index, (x, y) in enumerate(zip(a, b)):
            assert_identical(x, y, f"{where}[{index}]")
    else:
        assert a == b, f"{where}: {a!r} != {b!r}"


def random_valid_actions(env, infos: dict, rng: np.random.Generator) -> dict:
    """A uniformly drawn valid action for every live agent of a team env."""
    return {agent: int(rng.choice(np.flatnonzero(infos[agent]["action_mask"]))) for agent in env.agents}


def greedy_actions(env, infos: dict) -> dict:
    """Every live agent's valid action with the largest ``action_information_gain`` (lowest index on ties)."""
    return {
        agent: int(np.argmax(np.where(infos[agent]["action_mask"], infos[agent]["action_information_gain"], -1)))
        for agent in env.agents
    }


@contextlib.contextmanager
def unused_address():
    """``127.0.0.1:PORT`` of a port bound here but never listening (a connection to it is refused)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        yield f"127.0.0.1:{probe.getsockname()[1]}"


def map_footprints(model, positions) -> np.ndarray:
    """The reference of which cells of a ``TerrainMapModel`` a scan from each position (..., 2) [m] sees (..., G)
    bool: those whose centre lies within ``scan_radius_m`` (the compiled map visits only these)."""
    dx, dy = positions[..., 0, None] - model.ticks, positions[..., 1, None] - model.ticks  # (..., K) [m]
    squared = dx[..., None, :] * dx[..., None, :] + dy[..., :, None] * dy[..., :, None]  # (..., K rows, K)
    return squared.reshape(*squared.shape[:-2], -1) <= model.scan_radius_m**2


def select_candidates(chosen, *candidates) -> tuple[np.ndarray, ...]:
    """Each copy's chosen row of per-candidate arrays, and which copies chose one.

    Args:
        chosen: the chosen candidate of each copy (N,), -1 for none.
        candidates: arrays (N, K, ...) (e.g. the predicted measurements, Jacobians and noise of K landmarks).

    Returns:
        ``(observed (N,) bool, *rows)``, each row (N, ...); a copy with none gets its candidate 0 (unused).
    """
    chosen = np.asarray(chosen)
    observed = chosen >= 0
    copies, rows = np.arange(len(chosen)), np.where(observed, chosen, 0)
    return (observed, *(np.asarray(candidate)[copies, rows] for candidate in candidates))


def distance_to_loop(point, loop) -> float:
    """Shortest distance [m] from ``point`` (2,) to the closed polyline ``loop`` (W, 2); one vertex is a point."""
    from infonav_gym.geometry import ClosedLoop  # here: this module does not import infonav_gym (see above)

    return float(ClosedLoop(loop).distances(np.asarray(point, dtype=float)[None])[0])
