"""The Fig. 2 story on the corridor: per-step information contribution of the 4 landmarks, and the choices."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from tqdm import tqdm

from infonav_gym.estimation import batched
from infonav_gym.experiments.episodes import make_agent
from infonav_gym.information import expected_information_gain

DEMO_AGENTS = ("greedy", "random")
DEMO_HORIZON = 200  # [steps] the corridor episode each agent drives: the most steps a demo shows
PROGRESS_DELAY_S = 2.0  # the progress bar shows once a demo has run this long [s]


def run_demo(steps: int = 12, seed: int = 0, progress: bool = False) -> dict:
    """Both agents on the corridor for ``steps`` steps of one episode (at most ``DEMO_HORIZON``) with the same seed;
    one record per step. ``progress``: a bar on stderr once the demo runs longer than ``PROGRESS_DELAY_S``."""
    if not 1 <= steps <= DEMO_HORIZON:
        raise ValueError(f"steps must be in [1, {DEMO_HORIZON}] (one corridor episode), got {steps}")
    env = gym.make("infonav/LandmarkSelection-v0", scenario="corridor", n_candidates=4, horizon=DEMO_HORIZON)
    runs = {}
    bar = tqdm(total=steps * len(DEMO_AGENTS), desc="demo", unit="step", delay=PROGRESS_DELAY_S, disable=not progress)
    for name in DEMO_AGENTS:
        agent = make_agent(name, env.action_space.n)
        observation, info = env.reset(seed=seed)
        agent.reset(seed=seed)
        records = []
        for step in range(steps):
            gains = info["action_information_gain"].tolist()
            action = agent.act(observation, info)
            observation, reward, _, _, info = env.step(action)
            records.append(
                {
                    "step": step,
                    "information_contribution": gains,
                    "choice": action,
                    "realized": reward,
                    "pose_entropy": info["pose_entropy"],
                }
            )
            bar.update()
        runs[name] = records
    bar.close()
    env.close()
    return {"seed": seed, "steps": steps, "runs": runs}


def demo_table(demo: dict) -> str:
    """Per agent, a text table of the landmarks' information contributions and the choice made."""
    blocks = []
    for name, records in demo["runs"].items():
        lines = [
            f"{name} agent (landmarks numbered as in Fig. 1; ic in nats)",
            "step    ic #1   ic #2   ic #3   ic #4   choice  realized  pose entropy",
        ]
        for record in records:
            ics = "".join(f"{value:8.3f}" for value in record["information_contribution"])
            lines.append(
                f"{record['step']:4d}{ics}      #{record['choice'] + 1}  {record['realized']:8.3f}  "
                f"{record['pose_entropy']:12.3f}"
            )
        total = sum(record["realized"] for record in records)
        lines.append(f"total information gathered: {total:.3f} nats")
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks)


def figure_information_field(seed: int = 0, resolution: int = 80):
    """Fig. 2 as a picture: the ic a landmark would bring, over where it could be, from the start pose."""
    from infonav_gym.rendering import matplotlib_figure

    env = gym.make("infonav/LandmarkSelection-v0", scenario="corridor", n_candidates=4).unwrapped
    _, info = env.reset(seed=seed)
    model, sensor = env.vector, env.vector.sensor
    x, P = model.estimate(0)
    xs, ys = np.meshgrid(
        np.linspace(2.0, sensor.max_range_m + 1.0, resolution), np.linspace(-2.7, 2.7, resolution // 4)
    )
    positions = np.stack([xs.ravel(), ys.ravel()], axis=1)
    predicted, H = batched.landmark_measurement_model(x[None], positions[None])
    field = expected_information_gain(P, H[0], sensor.noise_covariance(predicted[0, :, 0])).reshape(xs.shape)
    figure = matplotlib_figure("the Fig. 2 plot", figsize=(9, 4.5))
    axes = figure.add_subplot(projection="3d")
    axes.plot_surface(xs, ys, field, cmap="viridis", alpha=0.35, linewidth=0.2, edgecolor="grey")
    landmarks = model.scenario(0).landmarks
    for index, (landmark, ic) in enumerate(zip(landmarks, info["action_information_gain"])):
        axes.plot([landmark[0]] * 2, [landmark[1]] * 2, [0.0, ic], color="red", linewidth=1.5)
        axes.scatter(*landmark, ic, color="red", marker="D", s=40, depthshade=False)
        axes.text(landmark[0], landmark[1], ic + 0.05, f"#{index + 1}: {ic:.2f}", color="darkred", zorder=10)
    axes.view_init(elev=25, azim=-60)
    axes.set_xlabel("landmark x [m]")
    axes.set_ylabel("landmark y [m]")
    axes.set_zlabel("ic [nats]")
    axes.set_title("Information contribution of a landmark, from the vehicle at the corridor start")
    env.close()
    return figure
