"""Loader for the UTIAS MRCLAM directory format (Leung et al., IJRR 2011).

A directory holds ``Barcodes.dat`` (subject -> barcode), ``Landmark_Groundtruth.dat`` and per robot ``N``
``RobotN_{Odometry,Measurement,Groundtruth}.dat``: numbers with ``#`` header lines. Measurements name a barcode,
mapped here to its subject. Times stay absolute [s]; replay times count from ``MRCLAMDataset.start_time``.
"""

from __future__ import annotations

import dataclasses
import re
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

BARCODES_FILE = "Barcodes.dat"
LANDMARKS_FILE = "Landmark_Groundtruth.dat"
ODOMETRY_COLUMNS, ODOMETRY_ROW = 3, "time [s], forward velocity [m/s], angular velocity [rad/s]"
MEASUREMENT_COLUMNS, MEASUREMENT_ROW = 4, "time [s], barcode #, range [m], bearing [rad]"
GROUNDTRUTH_COLUMNS, GROUNDTRUTH_ROW = 4, "time [s], x [m], y [m], orientation [rad]"
LANDMARK_COLUMNS, LANDMARK_ROW = 5, "subject #, x [m], y [m], x std-dev [m], y std-dev [m]"
_ROBOT_FILE = re.compile(r"Robot(\d+)_(Odometry|Measurement|Groundtruth)\.dat$")


@dataclass
class MRCLAMDataset:
    """One MRCLAM dataset in numpy arrays; robots and landmarks are named by subject number, rows time-sorted."""

    path: Path
    robots: tuple[int, ...]  # the robots with odometry, ascending
    barcodes: dict[int, int]  # barcode # -> subject #
    landmark_ids: np.ndarray  # the mapped landmarks (L,)
    landmarks: np.ndarray  # their [x, y] (L, 2) [m]
    landmark_std: np.ndarray  # their ground-truth standard deviations [x, y] (L, 2) [m]
    odometry: dict[int, np.ndarray]  # robot -> [time, speed, turn_rate] (n, 3)
    landmark_measurements: dict[int, np.ndarray]  # robot -> [time, landmark subject, range, bearing] (m, 4)
    robot_measurements: dict[int, np.ndarray]  # robot -> [time, observed robot subject, range, bearing] (m, 4)
    groundtruth: dict[int, np.ndarray]  # robot -> [time, x, y, heading] (g, 4); absent without the file
    unknown_barcodes: int = 0  # measurements skipped: their barcode names no robot or mapped landmark
    unknown_barcode_values: tuple[int, ...] = ()
    missing: list[str] = field(default_factory=list)  # notes on missing files (also warned)

    @property
    def start_time(self) -> float:
        """The first odometry time [s]: replay times count from here."""
        return float(min(self.odometry[robot][0, 0] for robot in self.robots if len(self.odometry[robot])))

    @property
    def end_time(self) -> float:
        """The last odometry time [s]."""
        return float(max(self.odometry[robot][-1, 0] for robot in self.robots if len(self.odometry[robot])))

    @property
    def has_groundtruth(self) -> bool:
        """Every robot has a ground-truth trajectory."""
        return all(robot in self.groundtruth for robot in self.robots)

    def within(self, start_s: float, end_s: float) -> MRCLAMDataset:
        """The dataset with only the log rows whose time lies in ``[start_s, end_s)`` after ``start_time`` [s]."""
        start, end = self.start_time + start_s, self.start_time + end_s

        def cut(tables):
            return {robot: rows[(rows[:, 0] >= start) & (rows[:, 0] < end)] for robot, rows in tables.items()}

        return dataclasses.replace(
            self,
            odometry=cut(self.odometry),
            landmark_measurements=cut(self.landmark_measurements),
            robot_measurements=cut(self.robot_measurements),
            groundtruth=cut(self.groundtruth),
        )

    def landmark_index(self, subjects) -> np.ndarray:
        """Row of each landmark subject number in ``landmarks``."""
        lookup = {int(subject): row for row, subject in enumerate(self.landmark_ids)}
        return np.array([lookup[int(subject)] for subject in np.atleast_1d(subjects)], dtype=int)


def read_table(path: Path, columns: int) -> np.ndarray:
    """A numeric table with ``#`` comments as (rows, ``columns``) float64; ``ValueError`` naming the file and line
    number of the first line without ``columns`` finite numbers."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # numpy warns on an empty file
        try:
            table = np.loadtxt(path, comments="#", ndmin=2, dtype=float)
        except ValueError:
            table = None
    if table is not None and table.size == 0:
        return np.zeros((0, columns))
    if table is None or table.shape[1] != columns or not np.all(np.isfinite(table)):
        _raise_on_first_bad_line(path, columns)
    return table


def _raise_on_first_bad_line(path: Path, columns: int) -> None:
    """The slow path of ``read_table``: find the malformed line and say where it is."""
    with open(path, encoding="utf-8", errors="replace") as lines:
        for number, line in enumerate(lines, start=1):
            fields = line.split("#", 1)[0].split()
            if not fields:
                continue
            problem = None
            if len(fields) != columns:
                problem = f"expected {columns} numbers, found {len(fields)}"
            else:
                try:
                    values = [float(value) for value in fields]
                except ValueError:
                    problem = "not all fields are numbers"
                else:
                    if not all(np.isfinite(values)):
                        problem = "a value is not finite"
            if problem:
                raise ValueError(f"{path}, line {number}: malformed line ({problem}): {line.strip()[:80]!r}")
    raise ValueError(f"{path}: could not read it as a table of {columns} numbers per line")


def _sorted_by_time(table: np.ndarray, path: Path, unique_times: bool = True) -> np.ndarray:
    """``table`` sorted by its time column (stable), without rows of negative times; warn, naming ``path``, about
    those and, when each row should have its own time (``unique_times``: odometry, ground truth), repeated ones."""
    table = table[np.argsort(table[:, 0], kind="stable")]
    negative = int(np.count_nonzero(table[:, 0] < 0))
    if negative:
        warnings.warn(f"{path}: {negative} row(s) with a negative timestamp, left out", stacklevel=3)
        table = table[table[:, 0] >= 0]
    repeated = int(np.count_nonzero(np.diff(table[:, 0]) == 0)) if unique_times else 0
    if repeated:
        warnings.warn(f"{path}: {repeated} row(s) repeat the timestamp of the row before", stacklevel=3)
    return table


def _required(directory: Path, name: str, columns: int, what: str) -> np.ndarray:
    """The rows of ``directory / name`` (``_rows``), which must exist."""
    path = directory / name
    if not path.is_file():
        raise FileNotFoundError(f"{path} is missing: {directory} is not an MRCLAM dataset directory")
    return _rows(path, columns, what)


def _rows(path: Path, columns: int, what: str) -> np.ndarray:
    """The table of ``path`` (``read_table``), which must hold at least one row (``what`` its columns are)."""
    table = read_table(path, columns)
    if not len(table):
        raise ValueError(f"{path} holds no rows (empty or only '#' comments): expected lines of {what}")
    return table


def load(path) -> MRCLAMDataset:
    """Read an MRCLAM dataset directory into numpy arrays.

    Robots are the subjects of ``Barcodes.dat`` without a landmark row. A robot without odometry is left out;
    missing measurement or ground-truth files, unknown barcodes (skipped), negative or repeated timestamps are
    warned about; rows out of time order are sorted.

    Raises:
        FileNotFoundError: if the directory, ``Barcodes.dat``, ``Landmark_Groundtruth.dat`` or all odometry is missing.
        NotADirectoryError: if ``path`` is a file.
        ValueError: on a malformed line (file and line number) or an empty file.
    """
    directory = Path(path)
    if directory.is_file():
        raise NotADirectoryError(
            f"{directory} is a file: give the MRCLAM dataset directory that holds {BARCODES_FILE} and the robot files"
        )
    if not directory.is_dir():
        raise FileNotFoundError(f"MRCLAM dataset directory {directory} does not exist")
    barcode_rows = _required(directory, BARCODES_FILE, 2, "subject #, barcode #").astype(int)
    landmark_rows = _required(directory, LANDMARKS_FILE, LANDMARK_COLUMNS, LANDMARK_ROW)
    barcodes = {int(barcode): int(subject) for subject, barcode in barcode_rows}
    landmark_ids = landmark_rows[:, 0].astype(int)
    candidate_robots = {int(subject) for subject in barcode_rows[:, 0]} - set(landmark_ids.tolist())
    candidate_robots.update(int(match[1]) for file in directory.iterdir() if (match := _ROBOT_FILE.match(file.name)))

    missing: list[str] = []
    odometry, raw_measurements, landmark_measurements, robot_measurements, groundtruth = {}, {}, {}, {}, {}
    for robot in sorted(candidate_robots):
        odometry_path = directory / f"Robot{robot}_Odometry.dat"
        if not odometry_path.is_file():
            missing.append(f"robot {robot}: {odometry_path.name} is missing, robot left out")
            continue
        odometry[robot] = _sorted_by_time(_rows(odometry_path, ODOMETRY_COLUMNS, ODOMETRY_ROW), odometry_path)
        raw_measurements[robot] = np.zeros((0, MEASUREMENT_COLUMNS))
        for kind, columns, what, tables, absent in (
            ("Measurement", MEASUREMENT_COLUMNS, MEASUREMENT_ROW, raw_measurements, "no measurements"),
            ("Groundtruth", GROUNDTRUTH_COLUMNS, GROUNDTRUTH_ROW, groundtruth, "no ground truth"),
        ):
            path = directory / f"Robot{robot}_{kind}.dat"
            if path.is_file():  # measurements may share a time, odometry and ground truth rows may not
                tables[robot] = _sorted_by_time(_rows(path, columns, what), path, unique_times=tables is groundtruth)
            else:
                missing.append(f"robot {robot}: {path.name} is missing, {absent}")
    robots = tuple(sorted(odometry))
    if not robots:
        raise FileNotFoundError(f"no RobotN_Odometry.dat in {directory}: nothing to replay")

    skipped: list[int] = []  # the barcodes of the measurements skipped
    for robot, rows in raw_measurements.items():
        subjects = np.array([barcodes.get(int(barcode), -1) for barcode in rows[:, 1]], dtype=int)
        is_landmark = np.isin(subjects, landmark_ids)
        is_robot = np.isin(subjects, [other for other in robots if other != robot])
        skipped += rows[~(is_landmark | is_robot), 1].astype(int).tolist()
        with_subjects = np.column_stack([rows[:, 0], subjects, rows[:, 2:]])
        landmark_measurements[robot] = with_subjects[is_landmark]
        robot_measurements[robot] = with_subjects[is_robot]
    if skipped:
        warnings.warn(
            f"{directory}: skipped {len(skipped)} measurements of barcodes that name no robot or mapped "
            f"landmark: {sorted(set(skipped))}",
            stacklevel=2,
        )
    for note in missing:
        warnings.warn(f"{directory}: {note}", stacklevel=2)
    return MRCLAMDataset(
        path=directory,
        robots=robots,
        barcodes=barcodes,
        landmark_ids=landmark_ids,
        landmarks=landmark_rows[:, 1:3].copy(),
        landmark_std=landmark_rows[:, 3:5].copy(),
        odometry=odometry,
        landmark_measurements=landmark_measurements,
        robot_measurements=robot_measurements,
        groundtruth=groundtruth,
        unknown_barcodes=len(skipped),
        unknown_barcode_values=tuple(sorted(set(skipped))),
        missing=missing,
    )
