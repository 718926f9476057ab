"""A synthetic directory in the MRCLAM format (two robots circling among three landmarks, exact logs): the loader's
and the replay's tests, and the dataset every test session points ``$INFONAV_MRCLAM_DATASET`` at (``conftest.py``).
Imports numpy only (``conftest.py`` must not import the package)."""

import math
from pathlib import Path

import numpy as np

HEADER = "# synthetic MRCLAM-format file\n# columns as in the published datasets\n"
LANDMARKS = {3: (2.0, 0.0), 4: (0.0, 2.0), 5: (-2.0, -1.0)}
BARCODES = {1: 11, 2: 22, 3: 33, 4: 44, 5: 55}  # subject -> barcode
UNKNOWN_BARCODE = 99
SPEED, TURN_RATE, DURATION_S = 0.2, 0.2, 20.0  # [m/s], [rad/s], [s] (the default length)


def write_rows(path: Path, rows) -> None:
    path.write_text(HEADER + "".join(" \t".join(f"{value:.6f}" for value in row) + "\n" for row in rows))


def true_pose(robot: int, t):
    """Robot 1 circles from (0, -1) heading east; robot 2 the same circle half a turn later."""
    phase = TURN_RATE * np.asarray(t) + (0.0 if robot == 1 else math.pi)
    radius = SPEED / TURN_RATE
    return np.stack([radius * np.sin(phase), -radius * np.cos(phase), phase], axis=-1)


def write_dataset(
    directory: Path, groundtruth: bool = True, duration_s: float = DURATION_S, field_of_view_rad: float = 2 * math.pi
) -> Path:
    """A two-robot, three-landmark directory with exact odometry and measurements (each 0.5 s, the other robot and
    every landmark within ``field_of_view_rad`` around the heading) for ``duration_s`` seconds, 1e9 s epoch like the
    real sets."""
    directory.mkdir(parents=True, exist_ok=True)
    epoch = 1.0e9
    write_rows(directory / "Barcodes.dat", [(subject, barcode) for subject, barcode in BARCODES.items()])
    write_rows(directory / "Landmark_Groundtruth.dat", [(s, x, y, 1e-4, 1e-4) for s, (x, y) in LANDMARKS.items()])
    odometry_times = np.arange(0.0, duration_s, 0.02)
    for robot in (1, 2):
        write_rows(directory / f"Robot{robot}_Odometry.dat", [(epoch + t, SPEED, TURN_RATE) for t in odometry_times])
        rows = []
        for t in np.arange(0.5, duration_s, 0.5):
            x, y, heading = true_pose(robot, t)
            targets = [(BARCODES[s], p) for s, p in LANDMARKS.items()] + [
                (BARCODES[3 - robot], true_pose(3 - robot, t))
            ]
            for barcode, (tx, ty, *_) in targets:
                bearing = math.remainder(math.atan2(ty - y, tx - x) - heading, 2 * math.pi)
                if abs(bearing) <= field_of_view_rad / 2 or barcode == BARCODES[3 - robot]:
                    rows.append((epoch + t, barcode, math.hypot(tx - x, ty - y), bearing))
        rows.append((epoch + 1.0, UNKNOWN_BARCODE, 1.0, 0.0))
        write_rows(directory / f"Robot{robot}_Measurement.dat", rows)
        if groundtruth:
            times = np.arange(0.0, duration_s, 0.01)
            write_rows(
                directory / f"Robot{robot}_Groundtruth.dat", np.column_stack([epoch + times, true_pose(robot, times)])
            )
    return directory
