"""The calibrated noise model of the MRCLAM robots: JSON schema, checks, and the shipped calibration.

A model holds, per robot subject (and ``pooled`` for robots it does not name), the ``RobotNoise`` that the replay's
``calibration.calibrate`` estimated from motion-capture ground truth. The shipped model
(``data/mrclam_dataset6_noise.json``, package data) was fitted on Dataset 6 by (from the repository root; it writes
the fit and its residual plot ``results/mrclam_dataset6_noise.png``)::

    infonav replay mrclam ../shared/datasets/MRCLAM_Dataset6 --calibrate results/mrclam_dataset6_noise.json
    cp results/mrclam_dataset6_noise.json infonav_gym/datasets/data/
"""

from __future__ import annotations

import dataclasses
import json
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

SCHEMA_VERSION = 2  # 2: range slope varying across the image, white range std quadratic, shared and odometry biases
SHIPPED_MODEL = "data/mrclam_dataset6_noise.json"  # inside this package
ODOMETRY_HORIZON_S = 64.0  # [s] the longest odometry window calibrated: the gap between fixes a filter bridges


def integrated_variance(window_s, white_density, bias_std, correlation_time_s):
    """Variance of the integral over ``window_s`` of white noise (density ``white_density``) plus a first-order
    Gauss-Markov bias (stationary std ``bias_std``, correlation time ``tau``):
    ``q^2 T + 2 sigma^2 tau^2 (T / tau - 1 + exp(-T / tau))`` (Gelb 1974, Table 3.8-1)."""
    T, tau = np.asarray(window_s, dtype=float), correlation_time_s
    return white_density**2 * T + 2 * bias_std**2 * tau**2 * (T / tau - 1 + np.exp(-T / tau))


@dataclass(frozen=True)
class RobotNoise:
    """One robot's calibrated errors (units in the names; ``*_std`` of odometry per second of travel)."""

    odometry_time_offset_s: float  # [s] add to odometry times to put them on the ground-truth clock
    measurement_time_offset_s: float  # [s] the same for measurement times
    speed_scale: float  # odometry speed / true speed
    turn_rate_scale: float  # odometry turn rate / true turn rate
    travel_heading_offset_rad: float  # [rad] the robot drives this far from its ground-truth heading (marker frame)
    speed_std: float  # [m/s] noise density of the corrected speed: its 1 s average errs by this
    turn_rate_std: float  # [rad/s] the same for the turn rate
    speed_bias_std: float  # [m/s] stationary std of the speed's slow (Gauss-Markov) error ...
    speed_correlation_time_s: float  # [s] ... and its correlation time
    turn_rate_bias_std: float  # [rad/s] the same for the turn rate
    turn_rate_correlation_time_s: float  # [s]
    range_bias_m: float  # [m] systematic range error: this ...
    range_bias_per_rad: float  # [m/rad] ... plus this times the measured bearing ...
    range_bias_per_rad2: float  # [m/rad^2] ... plus this times its square (the camera's image position) ...
    range_bias_per_m: float  # [m/m] ... plus the measured range times this ...
    range_bias_per_m_rad: float  # [1/rad] ... plus this times the bearing ...
    range_bias_per_m_rad2: float  # [1/rad^2] ... plus this times its square (a range read from the target's size
    # in the image errs in proportion to the range, by a factor that varies across the image)
    range_white_std_m: float  # [m] white range noise at 0 m ...
    range_white_std_per_m2: float  # [1/m] ... plus this times the squared range
    range_bias_std_m: float  # [m] stationary std of a target's slow range bias
    range_correlation_distance_m: float  # [m] its correlation length in distance driven
    range_shared_std_m: float  # [m] stationary std of the slow range bias every target shares
    range_shared_correlation_distance_m: float  # [m]
    range_outlier_fraction: float  # share of range errors beyond 4 std of the Gaussian model
    bearing_bias_rad: float  # [rad] systematic bearing error: a cubic in the measured bearing b ...
    bearing_bias_per_rad: float  # [rad/rad] ... this times b ...
    bearing_bias_per_rad2: float  # ... this times b^2 ...
    bearing_bias_per_rad3: float  # ... this times b^3
    bearing_white_std_rad: float  # [rad]
    bearing_bias_std_rad: float  # [rad]
    bearing_correlation_distance_m: float  # [m]
    bearing_shared_std_rad: float  # [rad]
    bearing_shared_correlation_distance_m: float  # [m]
    bearing_outlier_fraction: float

    def range_white_std(self, range_m):
        """White range noise std [m] at ``range_m``."""
        return self.range_white_std_m + self.range_white_std_per_m2 * np.asarray(range_m, dtype=float) ** 2

    def total_noise(self, range_m) -> np.ndarray:
        """Covariance (..., 2, 2) of the whole range-bearing error (white plus biases) at ``range_m`` (...,), for a
        filter without bias states."""
        noise = np.zeros((*np.shape(range_m), 2, 2))
        noise[..., 0, 0] = self.range_white_std(range_m) ** 2 + self.range_bias_std_m**2 + self.range_shared_std_m**2
        noise[..., 1, 1] = self.bearing_white_std_rad**2 + self.bearing_bias_std_rad**2 + self.bearing_shared_std_rad**2
        return noise

    def odometry_density(self, horizon_s: float = ODOMETRY_HORIZON_S) -> np.ndarray:
        """``[speed, turn rate]`` densities of the white noise whose integral over ``horizon_s`` has the variance
        of the fitted odometry error's (white plus slow bias): a filter without bias states that takes the
        odometry error as white stays consistent over gaps between fixes up to that long, and is conservative
        over shorter ones (Maybeck 1979, "Stochastic Models, Estimation and Control", Sec. 4.11)."""
        variances = [
            integrated_variance(horizon_s, self.speed_std, self.speed_bias_std, self.speed_correlation_time_s),
            integrated_variance(
                horizon_s, self.turn_rate_std, self.turn_rate_bias_std, self.turn_rate_correlation_time_s
            ),
        ]
        return np.sqrt(np.array(variances, dtype=float) / horizon_s)

    def correct_odometry(self, odometry: np.ndarray) -> np.ndarray:
        """``[time, speed, turn_rate]`` rows on the ground-truth clock with the scale errors removed."""
        shift = [self.odometry_time_offset_s, 0.0, 0.0]
        return (odometry + shift) / [1.0, self.speed_scale, self.turn_rate_scale]

    def range_bias(self, range_m, bearing_rad):
        """Systematic range error [m] of a measurement of ``range_m`` at ``bearing_rad``."""
        b = np.asarray(bearing_rad, dtype=float)
        return (
            self.range_bias_m
            + self.range_bias_per_rad * b
            + self.range_bias_per_rad2 * b**2
            + np.asarray(range_m, dtype=float)
            * (self.range_bias_per_m + self.range_bias_per_m_rad * b + self.range_bias_per_m_rad2 * b**2)
        )

    def bearing_bias(self, bearing_rad):
        """Systematic bearing error [rad] of a measurement at ``bearing_rad``."""
        b = np.asarray(bearing_rad, dtype=float)
        return (
            self.bearing_bias_rad
            + self.bearing_bias_per_rad * b
            + self.bearing_bias_per_rad2 * b**2
            + self.bearing_bias_per_rad3 * b**3
        )

    def correct_measurements(self, measurements: np.ndarray) -> np.ndarray:
        """``[time, subject, range, bearing]`` rows on the ground-truth clock with the systematic errors removed."""
        corrected = np.array(measurements, dtype=float)
        corrected[:, 0] += self.measurement_time_offset_s
        corrected[:, 2] -= self.range_bias(measurements[:, 2], measurements[:, 3])
        corrected[:, 3] -= self.bearing_bias(measurements[:, 3])
        return corrected


FIELDS = tuple(field.name for field in dataclasses.fields(RobotNoise))
SYSTEMATIC_FIELDS = {  # each channel's systematic error coefficients, in the order of calibration.systematic_design
    channel: tuple(name for name in FIELDS if name.startswith(f"{channel}_bias") and "_bias_std" not in name)
    for channel in ("range", "bearing")
}
OFFSETS = {"odometry_time_offset_s", "measurement_time_offset_s", "travel_heading_offset_rad"}  # any sign
OFFSETS |= {*SYSTEMATIC_FIELDS["range"], *SYSTEMATIC_FIELDS["bearing"]}
FRACTIONS = {"range_outlier_fraction", "bearing_outlier_fraction"}  # in [0, 1)
NONNEGATIVE = {  # may be 0 (a fit finds no slow or shared error, or a white range std all intercept or all slope)
    name for name in FIELDS if "_bias_std" in name or "_shared_std" in name or name.startswith("range_white_std")
}
TOP_LEVEL = {"schema_version", "description", "command", "robots", "pooled", "diagnostics"}


@dataclass(frozen=True)
class NoiseModel:
    """Per-robot noise (subject number -> ``RobotNoise``), ``pooled`` for the others, and where it came from."""

    robots: dict[int, RobotNoise]
    pooled: RobotNoise
    source: str
    description: str = ""
    command: str = ""
    diagnostics: dict = dataclasses.field(default_factory=dict, compare=False)

    def for_robot(self, subject: int) -> RobotNoise:
        """The robot's own calibration, or the pooled one for a robot the calibration did not see."""
        return self.robots.get(int(subject), self.pooled)

    def to_json(self) -> dict:
        """The model in the JSON schema ``load_noise_model`` reads."""
        return {
            "schema_version": SCHEMA_VERSION,
            "description": self.description,
            "command": self.command,
            "robots": {str(subject): dataclasses.asdict(noise) for subject, noise in sorted(self.robots.items())},
            "pooled": dataclasses.asdict(self.pooled),
            "diagnostics": self.diagnostics,
        }

    def save(self, path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.to_json(), indent=1) + "\n")
        return path


def _json_object(document, what: str, required, allowed, where: str) -> None:
    """``ValueError`` naming ``where`` unless ``document`` is a JSON object (``what``) with every ``required`` key
    (the first missing in their order is named) and no key but the ``allowed`` ones."""
    if not isinstance(document, dict):
        raise ValueError(f"{where}: expected {what}, got {type(document).__name__}")
    missing, unknown = [key for key in required if key not in document], sorted(document.keys() - set(allowed))
    if missing:
        raise ValueError(f"{where}: missing key {missing[0]!r}")
    if unknown:
        raise ValueError(f"{where}: unknown key {unknown[0]!r}")


def _robot_noise(values, where: str) -> RobotNoise:
    """``values`` (a JSON object) as ``RobotNoise``, or ``ValueError`` naming ``where`` and the key at fault."""
    _json_object(values, "an object of noise parameters", sorted(FIELDS), FIELDS, where)
    for key, value in values.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ValueError(f"{where}.{key}: expected a finite number, got {value!r}")
        if key in FRACTIONS and not 0 <= value < 1:
            raise ValueError(f"{where}.{key}: expected a fraction in [0, 1), got {value}")
        if key not in OFFSETS | FRACTIONS and (value < 0 or (value == 0 and key not in NONNEGATIVE)):
            kind = "non-negative" if key in NONNEGATIVE else "positive"
            raise ValueError(f"{where}.{key}: a std, scale or time must be {kind}, got {value}")
    return RobotNoise(**{key: float(value) for key, value in values.items()})


def parse_noise_model(document, source: str) -> NoiseModel:
    """Check a decoded JSON document against the schema; ``ValueError`` names ``source`` and the key."""
    _json_object(document, "a JSON object", ("schema_version", "robots", "pooled"), TOP_LEVEL, source)
    if document["schema_version"] != SCHEMA_VERSION:
        raise ValueError(
            f"{source}: schema_version {document['schema_version']!r} is not supported (expected {SCHEMA_VERSION})"
        )
    if not isinstance(document["robots"], dict):
        raise ValueError(f"{source}: robots: expected an object keyed by robot subject number")
    robots = {}
    for subject, values in document["robots"].items():
        if not str(subject).isdigit():
            raise ValueError(f"{source}: robots: key {subject!r} is not a robot subject number")
        robots[int(subject)] = _robot_noise(values, f"{source}: robots.{subject}")
    return NoiseModel(
        robots=robots,
        pooled=_robot_noise(document["pooled"], f"{source}: pooled"),
        source=source,
        description=str(document.get("description", "")),
        command=str(document.get("command", "")),
        diagnostics=document.get("diagnostics", {}),
    )


def load_noise_model(path) -> NoiseModel:
    """Read a calibration JSON file.

    Raises:
        FileNotFoundError: if ``path`` is not a file.
        ValueError: if it is not JSON, or misses a key, has an unknown one, a negative std or another
            schema version (the message names the file and the key).
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"noise model file {path} does not exist")
    try:
        document = json.loads(path.read_text())
    except json.JSONDecodeError as error:
        raise ValueError(f"{path}: not valid JSON ({error})") from None
    return parse_noise_model(document, str(path))


def shipped_noise_model() -> NoiseModel:
    """The model calibrated on MRCLAM Dataset 6 (package data)."""
    text = resources.files(__package__).joinpath(SHIPPED_MODEL).read_text()
    return parse_noise_model(json.loads(text), f"{__package__}/{SHIPPED_MODEL} (package data)")


def corrected_logs(dataset, model: NoiseModel | None):
    """``dataset`` (itself without a ``model``) with each robot's logs on the ground-truth clock, odometry scales
    and mean range / bearing errors removed (``RobotNoise.correct_odometry`` / ``correct_measurements``)."""
    if not model:
        return dataset

    def corrected(tables, correct):
        return {robot: correct(model.for_robot(robot), rows) for robot, rows in tables.items()}

    return dataclasses.replace(
        dataset,
        odometry=corrected(dataset.odometry, RobotNoise.correct_odometry),
        landmark_measurements=corrected(dataset.landmark_measurements, RobotNoise.correct_measurements),
        robot_measurements=corrected(dataset.robot_measurements, RobotNoise.correct_measurements),
    )
