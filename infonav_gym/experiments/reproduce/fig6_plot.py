"""Fig. 6 as a picture: the newer frame over the older one, placed by odometry (before) and by ICP (after)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from infonav_gym.geometry import transform_points
from infonav_gym.registration.frame_pairs import FramePair
from infonav_gym.registration.icp import estimate_normals
from infonav_gym.rendering import require_extra
from infonav_gym.sensors.ladar import sensor_points

_VIEWS = (("top view", 0, 1, "x [m]", "y [m]"), ("side view", 0, 2, "x [m]", "z [m]"))
_POINT_SIZE = 1.5
_RESIDUAL_SCALE_M = 0.2  # colour scale of the residuals [m]


def plot_fig6(pair: FramePair, icp_motion: np.ndarray, registration: dict, path: Path) -> None:
    """Write ``path``: rows = top and side views, columns = before (odometry) and after (ICP) registration.

    Points are in the older frame's body frame at its optical centre: the older frame in gray,
    the newer one coloured by its distance to the older frame's surface (to the tangent plane at
    the closest older point: the point-to-plane residual; misregistration shows as warm colours).
    """
    require_extra("matplotlib", "plotting Fig. 6")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    target = sensor_points(pair.previous)
    source = sensor_points(pair.current)
    tree = cKDTree(target)
    normals = estimate_normals(target, tree)
    placements = (
        ("(a) before: odometry estimate", pair.odometry_motion, registration["error_before_m"]),
        ("(b) after: ICP registration", icp_motion, registration["error_after_m"]),
    )
    figure, axes = plt.subplots(2, 2, figsize=(13, 8), constrained_layout=True)
    for column, (title, motion, error) in enumerate(placements):
        placed = transform_points(motion, source)
        closest = tree.query(placed)[1]
        residual = np.abs(np.einsum("ij,ij->i", placed - target[closest], normals[closest]))
        for row, (view, first, second, first_label, second_label) in enumerate(_VIEWS):
            ax = axes[row, column]
            ax.scatter(
                target[:, first],
                target[:, second],
                s=_POINT_SIZE,
                c="0.75",
                label="older frame (newer: coloured)",
                lw=0,
            )
            points = ax.scatter(
                placed[:, first],
                placed[:, second],
                s=_POINT_SIZE,
                c=residual,
                cmap="turbo",
                vmin=0.0,
                vmax=_RESIDUAL_SCALE_M,
                lw=0,
            )
            ax.set_title(f"{title}, {view}: error {error:.3f} m", fontsize="medium")
            ax.set_xlabel(first_label)
            ax.set_ylabel(second_label)
            if row == 0:
                ax.set_aspect("equal", adjustable="datalim")
            ax.legend(loc="upper right", markerscale=6, fontsize="small")
    figure.colorbar(points, ax=axes, shrink=0.6, label="newer point to the older frame's surface [m]")
    figure.suptitle(
        "Fig. 6: consecutive 3D LADAR frames (32 x 180) of a vehicle pitching and rolling over rugged terrain, "
        f"before and after ICP ({registration['points']} points, {registration['iterations']} iterations)"
    )
    figure.savefig(path, dpi=120)
    plt.close(figure)
