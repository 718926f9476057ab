"""Pymunk is the physics of record: every env's episodes, run in a world where Pymunk takes every step, find the
same robot poses as the batched world (whose contact-free steps run in compiled numpy).

``WorldBatch`` steps a copy in its own Pymunk space only when a contact may happen; here that test is forced to
say "maybe" everywhere, so every step of every copy goes through ``ContactSpace.drive`` (Chipmunk's solver
and integrator). The same seeds and actions must then give the same true poses to 1e-9 m, step by step.
"""

from __future__ import annotations

import numpy as np
import pytest

from infonav_gym.registry import make_vector_env, registered_envs
from infonav_gym.world import world_batch

POSE_TOLERANCE_M = 1e-9
N_COPIES, N_STEPS = 2, 40
WORLD_ENV_IDS = [
    entry.id
    for entry in registered_envs()
    if entry.vector_entry_point is not None and entry.id != "infonav/SensorSelection-v0"  # no robots
]


def _pymunk_only(monkeypatch) -> None:
    """Make every step of every copy a Pymunk step: a contact is always within reach and never ruled out."""

    def always_within(copies, poses, *_):
        everywhere = np.ones(np.shape(poses)[:1], dtype=bool)
        return everywhere, everywhere

    monkeypatch.setattr(world_batch, "contact_within", always_within)
    monkeypatch.setattr(world_batch, "contact_free", lambda copies, *_: np.zeros(len(copies), dtype=bool))


def _true_pose_trajectory(env_id: str, seed: int) -> list[np.ndarray]:
    """The true poses in the infos of ``N_STEPS`` steps of random valid actions (drawn from ``seed``)."""
    env = make_vector_env(env_id, num_envs=N_COPIES)
    rng = np.random.default_rng(seed)
    _, info = env.reset(seed=seed)
    poses = [np.asarray(info["true_pose"], dtype=float)]
    for _ in range(N_STEPS):
        masks = env.action_masks()
        scores = np.where(masks, rng.random(masks.shape), -1.0)
        _, _, _, _, info = env.step(np.argmax(scores, axis=-1))
        poses.append(np.asarray(info["true_pose"], dtype=float))
    env.close()
    return poses


@pytest.mark.parametrize("env_id", WORLD_ENV_IDS)
def test_episodes_in_a_pymunk_only_world_find_the_same_robot_poses(env_id, monkeypatch):
    batched = _true_pose_trajectory(env_id, seed=3)
    _pymunk_only(monkeypatch)
    pymunk_only = _true_pose_trajectory(env_id, seed=3)
    for step, (ours, reference) in enumerate(zip(batched, pymunk_only)):
        error = np.abs(ours[..., :2] - reference[..., :2]).max()
        heading_error = np.abs(np.angle(np.exp(1j * (ours[..., 2] - reference[..., 2])))).max()
        assert error <= POSE_TOLERANCE_M and heading_error <= POSE_TOLERANCE_M, (
            f"{env_id} step {step}: position error {error:.3g} m, heading error {heading_error:.3g} rad"
        )


def test_the_pymunk_only_world_really_steps_in_pymunk(monkeypatch):
    """The oracle is not vacuous: forced, every copy builds and steps its own Pymunk space."""
    steps = []
    original = world_batch.ContactSpace.drive
    monkeypatch.setattr(world_batch.ContactSpace, "drive", lambda self, *args: steps.append(1) or original(self, *args))
    _pymunk_only(monkeypatch)
    env = make_vector_env(WORLD_ENV_IDS[0], num_envs=N_COPIES)
    env.reset(seed=0)
    env.step(np.zeros(env.action_space.shape, dtype=int))
    assert len(steps) >= N_COPIES
