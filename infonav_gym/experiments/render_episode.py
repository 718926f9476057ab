"""One seeded episode of an env and an agent (as ``infonav evaluate`` plays it), rendered: an animated GIF and a
strip of frames (``infonav render``)."""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from tqdm.auto import tqdm

from infonav_gym.experiments.episode_pool import EpisodeRunner, check_positive
from infonav_gym.rendering import matplotlib_figure, require_extra

STRIP_FRAMES = 6  # frames in PREFIX.png
STRIP_COLUMNS = 3
STRIP_DPI = 100  # one frame pixel to one PNG pixel
STRIP_TITLE_IN = 0.4  # above every row of frames, and the strip's title on top [in]


def frame_stem(env_id: str) -> str:
    """An env's file stem in ``docs/frames``: its id without namespace and version (``LandmarkSelection``)."""
    return re.sub(r"-v\d+$", "", env_id.rpartition("/")[2])


@dataclass(frozen=True)
class RenderedEpisode:
    """The kept frames of an episode, (H, W, 3) uint8, the step each shows (0: after the reset), the env's fps."""

    frames: list
    steps: list
    fps: float


def render_episode(
    env_id: str,
    agent_name: str,
    seed: int,
    env_kwargs: dict | None = None,
    every: int = 1,
    max_steps: int | None = None,
    progress: bool = True,
) -> RenderedEpisode:
    """Play one episode (``agent_name`` as ``make_agent`` takes) and keep the frame after the reset, after every
    ``every``-th step and after the last; ``max_steps``: stop after that many."""
    check_positive(every, "--every")
    if max_steps is not None:
        check_positive(max_steps, "--max-steps")
    runner = EpisodeRunner(env_id, {**(env_kwargs or {}), "render_mode": "rgb_array"}, [agent_name])
    frames, steps = [], []
    spec = getattr(runner.env, "spec", None)  # the horizon: its Gymnasium time limit, or a team env's max_cycles
    horizon = spec.max_episode_steps if spec is not None else getattr(runner.env, "max_cycles", None)
    bar = tqdm(total=max_steps or horizon, desc=f"rendering {env_id}", disable=not progress, unit="step")
    try:
        stop = None if max_steps is None else max_steps + 1  # the reset, then max_steps steps
        for step, _ in enumerate(itertools.islice(runner.infos((agent_name, seed)), stop)):
            if step % every == 0:
                frames.append(runner.env.render())
                steps.append(step)
            bar.update(int(step > 0))
        if steps[-1] != step:
            frames.append(runner.env.render())
            steps.append(step)
    finally:
        bar.close()
        runner.close()
    return RenderedEpisode(frames, steps, float(runner.env.metadata["render_fps"]))


def write_gif(episode: RenderedEpisode, path: Path) -> Path:
    """The episode's frames as an animated GIF looping forever, at the env's fps (needs Pillow)."""
    require_extra("PIL", "infonav render's GIF")
    from PIL import Image

    images = [Image.fromarray(frame) for frame in episode.frames]
    frame_ms = round(1000 / episode.fps)
    images[0].save(path, save_all=True, append_images=images[1:], duration=frame_ms, loop=0, optimize=True)
    return path


def strip_indices(n_frames: int, n_shown: int = STRIP_FRAMES) -> list[int]:
    """``n_shown`` (at most ``n_frames``) evenly spaced frame indices, the first and the last included."""
    return sorted(set(np.rint(np.linspace(0, n_frames - 1, min(n_shown, n_frames))).astype(int).tolist()))


def figure_strip(episode: RenderedEpisode, title: str):
    """A grid of ``STRIP_FRAMES`` evenly spaced frames, one frame pixel to one PNG pixel at ``STRIP_DPI``."""
    frames, steps = episode.frames, episode.steps
    shown = strip_indices(len(frames))
    columns = min(STRIP_COLUMNS, len(shown))
    rows = -(-len(shown) // columns)
    height, width = (size / STRIP_DPI for size in frames[0].shape[:2])  # [in]
    titles = STRIP_TITLE_IN * (rows + 2)  # the strip's title takes two bands
    figure = matplotlib_figure("infonav render's PNG", figsize=(columns * width, rows * height + titles))
    axes = figure.subplots(rows, columns, squeeze=False)
    top = 1 - 2 * STRIP_TITLE_IN / figure.get_figheight()
    figure.subplots_adjust(left=0, right=1, bottom=0, top=top, wspace=0, hspace=STRIP_TITLE_IN / height)
    for axis in axes.ravel():
        axis.set_axis_off()
    for axis, index in zip(axes.ravel(), shown):
        axis.imshow(frames[index], interpolation="none")
        axis.set_title(f"step {steps[index]}", fontsize=11)
    figure.suptitle(title, fontsize=12, y=1 - STRIP_TITLE_IN / 4 / figure.get_figheight(), va="top")
    return figure
