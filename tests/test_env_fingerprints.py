"""``scripts/env_fingerprints.py``: a hash of every env's outputs that a refactor must leave unchanged; it must see
what changes and only that."""

from __future__ import annotations

import hashlib
import importlib.util
from pathlib import Path

import numpy as np

SCRIPT = Path(__file__).resolve().parent.parent / "scripts" / "env_fingerprints.py"
spec = importlib.util.spec_from_file_location("env_fingerprints", SCRIPT)
fingerprints = importlib.util.module_from_spec(spec)
spec.loader.exec_module(fingerprints)


def hashed(value) -> str:
    hasher = hashlib.sha256()
    fingerprints.digest(value, hasher)
    return hasher.hexdigest()


def test_the_hash_sees_values_not_addresses_and_leaves_out_wall_clock_times():
    info = {"sensor": np.array([{"kind": "ladar"}, None], dtype=object), "reward": np.float64(0.25)}
    same = {"reward": np.float64(0.25), "sensor": np.array([{"kind": "ladar"}, None], dtype=object)}
    assert hashed(info) == hashed(same)
    assert hashed(info) != hashed({**info, "reward": np.float64(0.25 + 1e-16 * 2)})
    assert hashed(info) != hashed({**info, "sensor": np.array([{"kind": "camera"}, None], dtype=object)})
    assert hashed({**info, "icp_time_s": 0.01}) == hashed({**info, "icp_time_s": 0.02})


def test_a_single_env_and_a_vector_env_hash_the_same_twice():
    env_id = "infonav/LandmarkSelection-v0"
    assert fingerprints.single_view(env_id) == fingerprints.single_view(env_id)
    assert fingerprints.vector_view(env_id, "same_step") == fingerprints.vector_view(env_id, "same_step")
