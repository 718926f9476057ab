"""Render a mid-episode frame and a short animated episode of every registered env into ``docs/frames``.

Usage: python scripts/render_frames.py [--output-dir DIR] [--env ENV_ID ...]. Each env plays the episode
``infonav render`` plays (the greedy-entropy agent from ``reset(seed=0)``); ``<name>.png`` is its frame after
``FRAME_STEPS`` steps, ``<name>.gif`` its first ``GIF_STEPS`` steps at ``GIF_SIZE_PX`` (``frame_stem`` names them).
"""

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

from PIL import Image

from infonav_gym.experiments.render_episode import frame_stem, render_episode, write_gif
from infonav_gym.registry import available_envs

SEED = 0
AGENT = "greedy"
FRAME_STEPS = 12  # steps before the frame, unless FRAME_SETTINGS says otherwise
FRAME_SETTINGS = {  # env id: (config, steps before the frame) where another moment shows the env better
    "infonav/LandmarkSelection-v0": ({"scenario": "corridor", "render_size_px": 900}, 12),
    "infonav/SensorSelection-v0": ({}, 20),
    "infonav/RangeRegistration-v0": ({}, 10),
    "cooperative_localization_v0": ({}, 80),
}
GIF_STEPS = 40  # steps in each GIF (the reset's frame first)
GIF_EVERY = 2  # keep every GIF_EVERY-th step's frame
GIF_SIZE_PX = 400  # render_size_px of the GIF frames: small files


def write_frame(env_id: str, output_dir: Path) -> Path:
    """The env's frame after its ``FRAME_SETTINGS`` steps (default ``FRAME_STEPS``), as ``<stem>.png``."""
    config, steps = FRAME_SETTINGS.get(env_id, ({}, FRAME_STEPS))
    episode = render_episode(env_id, AGENT, SEED, config, every=steps, max_steps=steps, progress=False)
    if episode.steps[-1] != steps:
        raise RuntimeError(f"{env_id} ended before step {steps}; render an earlier step")
    path = output_dir / f"{frame_stem(env_id)}.png"
    Image.fromarray(episode.frames[-1]).save(path)
    return path


def write_episode_gif(env_id: str, output_dir: Path) -> Path:
    """The env's first ``GIF_STEPS`` steps (every ``GIF_EVERY``-th frame) as ``<stem>.gif``."""
    config = {**FRAME_SETTINGS.get(env_id, ({}, FRAME_STEPS))[0], "render_size_px": GIF_SIZE_PX}
    episode = render_episode(env_id, AGENT, SEED, config, every=GIF_EVERY, max_steps=GIF_STEPS, progress=False)
    return write_gif(episode, output_dir / f"{frame_stem(env_id)}.gif")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output-dir", type=Path, default=Path("docs/frames"), help="default: docs/frames")
    parser.add_argument("--env", action="append", help="only this env (repeatable; default: every registered env)")
    args = parser.parse_args(argv)
    args.output_dir.mkdir(parents=True, exist_ok=True)
    for env_id in args.env or [entry.id for entry in available_envs()]:
        for path in (write_frame(env_id, args.output_dir), write_episode_gif(env_id, args.output_dir)):
            print(f"wrote {path} ({path.stat().st_size / 1e3:.0f} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
