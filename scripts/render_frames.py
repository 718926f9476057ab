"""Render one mid-episode ``rgb_array`` frame of every env to ``docs/frames/<env>.png``.

Usage: python scripts/render_frames.py [--output-dir DIR]. Each env runs from ``reset(seed=0)``
under the greedy-entropy agent for the stated number of steps, then renders once.
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import gymnasium as gym
import numpy as np
from PIL import Image

import infonav_gym  # noqa: F401  (registers the envs)
from agents import GreedyEntropyAgent
from infonav_gym.multi import cooperative_localization_v0

SEED = 0
SINGLE_AGENT_FRAMES = {  # file name: (env id, config, steps before the frame)
    "LandmarkSelection": ("infonav/LandmarkSelection-v0", {"scenario": "corridor", "render_size_px": 900}, 12),
    "ActiveLocalization": ("infonav/ActiveLocalization-v0", {}, 12),
    "SensorSelection": ("infonav/SensorSelection-v0", {}, 20),
    "RangeRegistration": ("infonav/RangeRegistration-v0", {}, 10),
}
TEAM_FRAME = ("cooperative_localization_v0", 80)  # file name, steps before the frame


def single_agent_frame(env_id: str, config: dict, steps: int) -> np.ndarray:
    """The frame of ``env_id`` after ``steps`` greedy steps from ``reset(seed=SEED)``."""
    env = gym.make(env_id, render_mode="rgb_array", **config)
    agent = GreedyEntropyAgent()
    observation, info = env.reset(seed=SEED)
    for _ in range(steps):
        observation, _, terminated, truncated, info = env.step(agent.act(observation, info))
        if terminated or truncated:
            raise RuntimeError(f"{env_id} ended before step {steps}; render an earlier step")
    frame = env.render()
    env.close()
    return frame


def team_frame(steps: int) -> np.ndarray:
    """The team env's frame after ``steps`` greedy steps of every robot from ``reset(seed=SEED)``."""
    env = cooperative_localization_v0.parallel_env(render_mode="rgb_array")
    agent = GreedyEntropyAgent()
    observations, infos = env.reset(seed=SEED)
    for _ in range(steps):
        actions = {name: agent.act(observations[name], infos[name]) for name in env.agents}
        observations, _, _, _, infos = env.step(actions)
    frame = env.render()
    env.close()
    return frame


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=Path("docs/frames"), help="default: docs/frames")
    output_dir = parser.parse_args(argv).output_dir
    output_dir.mkdir(parents=True, exist_ok=True)
    frames = {name: single_agent_frame(*spec) for name, spec in SINGLE_AGENT_FRAMES.items()}
    frames[TEAM_FRAME[0]] = team_frame(TEAM_FRAME[1])
    for name, frame in frames.items():
        path = output_dir / f"{name}.png"
        Image.fromarray(frame).save(path)
        print(f"wrote {path} ({frame.shape[1]} x {frame.shape[0]} px)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
