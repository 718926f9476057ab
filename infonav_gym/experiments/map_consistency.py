"""Is ``infonav/MapRegistration-v0``'s fix covariance consistent? The NEES of its fused fixes against the truth, over
at least ``registrations`` fixes per agent on the env's own worlds (``scripts/map_registration_consistency.py``).

A fix's NEES is ``e^T R^-1 e``, ``e`` its planar pose error (x, y, yaw) and ``R`` its covariance: chi-square with 3
degrees of freedom if ``R`` is right (mean 3; the acceptance band of issue 44 is a mean in [2, 4]). A fused fix more
than ``FAILURE_SIGMAS`` off (NEES > 9) is a failure: 2.9 % of a consistent filter's fixes.
"""

from __future__ import annotations

import numpy as np
from scipy import stats
from tqdm.auto import tqdm

from infonav_gym.experiments.episodes import make_agent
from infonav_gym.registry import make_env
from infonav_gym.rendering import matplotlib_figure, save_figure

ENV_ID = "infonav/MapRegistration-v0"
DOF = 3
BAND = (2.0, 4.0)  # the accepted mean NEES


def fused_nees(agent_name: str, registrations: int, first_seed: int = 0, progress: bool = False) -> dict:
    """The NEES of every fused fix of ``agent_name`` over episodes from ``first_seed`` on until ``registrations`` were
    fused, and how many steps tried one and had it refused."""
    env = make_env(ENV_ID)
    agent = make_agent(agent_name, env.action_space.n, noop_action=0, env=env)
    nees, tried, refused, seeds = [], 0, 0, []
    with tqdm(total=registrations, desc=f"{agent_name} fixes", unit="fix", disable=not progress) as bar:
        seed = first_seed
        while len(nees) < registrations:
            agent.reset(seed)
            observation, info = env.reset(seed=seed)
            seeds.append(seed)
            done = False
            while not done:
                observation, _, terminated, truncated, info = env.step(agent.act(observation, info))
                done = terminated or truncated
                tried += int(info["registered_points"] > 0)
                refused += int(info["refused"])
                if info["fused"]:
                    nees.append(float(info["registration_nees"]))
                    bar.update()
            seed += 1
    env.close()
    return {"agent": agent_name, "seeds": [seeds[0], seeds[-1]], "nees": nees, "tried": tried, "refused": refused}


def summary(run: dict) -> dict:
    """Mean NEES, the fraction in the two-sided 95 % chi-square band, failures, refusals."""
    nees = np.asarray(run["nees"])
    low, high = stats.chi2.ppf([0.025, 0.975], DOF)
    return {
        "agent": run["agent"],
        "seeds": run["seeds"],
        "fused": len(nees),
        "mean_nees": float(nees.mean()),
        "median_nees": float(np.median(nees)),
        "inside_95_band": float(np.mean((nees >= low) & (nees <= high))),
        "failures": int(np.count_nonzero(nees > 9.0)),
        "failure_rate": float(np.mean(nees > 9.0)),
        "refused_rate": run["refused"] / max(run["tried"], 1),
        "in_band": bool(BAND[0] <= nees.mean() <= BAND[1]),
    }


def consistency_markdown(summaries: list[dict], command: str) -> str:
    """The table of ``summary`` rows, with how to read it."""
    lines = [
        f"Made by `{command}`.",
        "",
        f"NEES of the fused fixes of `{ENV_ID}` at its defaults against the truth (planar pose, {DOF} dof: mean 3 "
        f"if the covariance is right; accepted: a mean in [{BAND[0]:g}, {BAND[1]:g}]). A failure is a fused fix "
        "more than 3 sigma off (NEES > 9; 2.9 % of a consistent filter's). Refused: the fixes the EKF's NIS gate "
        "or ICP's convergence turned away, of the steps that registered.",
        "",
        "| agent | seeds | fused fixes | mean NEES | median | in the 95 % band | failures | refused | mean in band |",
        "| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for row in summaries:
        lines.append(
            f"| {row['agent']} | {row['seeds'][0]}..{row['seeds'][1]} | {row['fused']} | {row['mean_nees']:.2f} | "
            f"{row['median_nees']:.2f} | {100 * row['inside_95_band']:.1f} % | {row['failures']} "
            f"({100 * row['failure_rate']:.1f} %) | {100 * row['refused_rate']:.1f} % | "
            f"{'yes' if row['in_band'] else 'no'} |"
        )
    return "\n".join(lines) + "\n"


def plot_nees(runs: list[dict], path) -> None:
    """Each agent's NEES histogram over the chi-square density it should follow."""
    figure = matplotlib_figure("plotting the NEES of the map fixes", figsize=(7, 4), constrained_layout=True)
    axes = figure.subplots()
    edges = np.linspace(0, 15, 61)
    for run in runs:
        axes.hist(np.minimum(run["nees"], edges[-1]), edges, density=True, histtype="step", label=run["agent"])
    grid = np.linspace(0.01, edges[-1], 300)
    axes.plot(grid, stats.chi2.pdf(grid, DOF), "k--", label=f"chi-square, {DOF} dof")
    axes.set_xlabel("NEES of a fused fix (last bin: 15 and more)")
    axes.set_ylabel("density")
    axes.set_title(f"{ENV_ID}: fix covariance against the truth")
    axes.legend()
    save_figure(figure, path, dpi=100)


def check_registrations(registrations: int) -> int:
    """``registrations`` as an int in 1..10^6, or ``ValueError``."""
    if isinstance(registrations, bool) or not isinstance(registrations, int) or not 1 <= registrations <= 10**6:
        raise ValueError(f"registrations must be an integer in 1..1000000, got {registrations!r}")
    return registrations
