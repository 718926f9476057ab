"""What ``SensorSelection-v0`` acquires: its LADAR and camera on the pan-tilt platform, their options and frames."""

from __future__ import annotations

import math

import numpy as np

from infonav_gym.config import from_config
from infonav_gym.information import histogram_entropy
from infonav_gym.sensors.camera import Camera
from infonav_gym.sensors.ladar import Ladar, to_display_image
from infonav_gym.world.terrain import Terrain

SENSORS = ("ladar", "camera")
IDLE_ACTION = 0
MAX_IMAGE_ENTROPY = math.log(256)  # entropy of a uniform 256-level histogram [nats]
_BYTES_PER_PIXEL = {"ladar": 2, "camera": 1}  # 16-bit ranges, 8-bit gray levels
_CONFIG_FIELDS = {  # the fields of each sensor an env config sets
    "ladar": ("rows", "columns", "vertical_fov_rad", "horizontal_fov_rad", "range_std_m", "max_range_m"),
    "camera": ("rows", "columns", "horizontal_fov_rad", "noise_std"),
}


def sensor_config() -> dict:
    """The env config keys of the two sensors (``camera_noise_std`` in gray levels), with the sensors' defaults."""
    sensors = {"ladar": Ladar(), "camera": Camera()}
    return {
        f"{name}_{field}": getattr(sensors[name], field) for name, fields in _CONFIG_FIELDS.items() for field in fields
    }


class ImageSensors:
    """The vehicle's LADAR and camera, the bytes of a frame of each, and the (sensor, pan) of each action.

    Action ``1 + s * n_pan_sectors + p`` acquires sensor ``SENSORS[s]`` panned to ``pan_angles_rad[p]``, spread
    evenly over ``pan_span_rad`` from left to right; action 0 (``IDLE_ACTION``) acquires nothing.

    Raises:
        ValueError: naming the config key of ``owner``, for a bad sensor parameter or a buffer smaller than any
            frame.
    """

    def __init__(self, config: dict, owner: str):
        self.ladar = from_config(Ladar, config, _prefixed_keys(config, "ladar_"), owner)
        self.camera = from_config(Camera, config, _prefixed_keys(config, "camera_"), owner)
        self.frame_bytes = {
            "ladar": _BYTES_PER_PIXEL["ladar"] * self.ladar.rows * self.ladar.columns,
            "camera": _BYTES_PER_PIXEL["camera"] * self.camera.rows * self.camera.columns,
        }
        smallest = min(self.frame_bytes.values())
        if config["bandwidth_buffer_bytes"] < smallest:
            raise ValueError(
                f"config key 'bandwidth_buffer_bytes' of {owner} must hold at least one frame "
                f"({smallest} bytes), got {config['bandwidth_buffer_bytes']}"
            )
        n_pan = config["n_pan_sectors"]
        self.pan_angles_rad = np.linspace(0.5, -0.5, n_pan) * config["pan_span_rad"] if n_pan > 1 else np.zeros(1)
        self.n_options = len(SENSORS) * n_pan
        self.option_costs = np.repeat([self.frame_bytes[name] for name in SENSORS], n_pan)  # bytes per option

    def option(self, action: int) -> tuple[str, float]:
        """The ``(sensor name, pan angle [rad])`` that acquisition ``action`` (>= 1) uses."""
        sensor, sector = divmod(action - 1, len(self.pan_angles_rad))
        return SENSORS[sensor], float(self.pan_angles_rad[sector])

    def options(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per action (n,): the sensor's index in ``SENSORS`` (-1 for the idle action and the no-op -1; numbers, as
        TorchRL's info readers need) and pan angle [rad]."""
        acquiring = actions > IDLE_ACTION
        sensor, sector = np.divmod(np.where(acquiring, actions - 1, 0), len(self.pan_angles_rad))
        return np.where(acquiring, sensor, -1), np.where(acquiring, self.pan_angles_rad[sector], 0.0)

    def sensor(self, name: str) -> Ladar | Camera:
        """The sensor called ``name`` (one of ``SENSORS``)."""
        return self.ladar if name == "ladar" else self.camera

    def acquire(self, terrain: Terrain, pose: np.ndarray, np_random: np.random.Generator, name: str, pan_rad: float):
        """A uint8 image from sensor ``name`` panned by ``pan_rad`` at the true ``pose`` (LADAR: the display image)."""
        if name == "ladar":
            return to_display_image(self.ladar.scan(terrain, pose, np_random, pan_rad=pan_rad))
        return self.camera.capture(terrain, pose, np_random, pan_rad=pan_rad)


def acquire_frames(sensors: ImageSensors, terrains, poses, generators, copies, actions) -> tuple[list, np.ndarray]:
    """The frames that ``copies`` (n,) acquire with acquisition ``actions`` (n,) (>= 1), and their entropies (n,).

    Copy ``copies[k]`` renders its own terrain from ``poses[k]`` with noise from its own generator: one compiled
    pass over the rays each (the copies differ in terrain, pose and sensor, so they are looped over here). Profile
    of a step (random valid actions, 0.75 frames per step): at N = 1 the ray casting ~45 %, the shading, noise and
    entropy ~30 %, the rest ~25 %; at N = 256 ~65 %, ~35 % and ~1 %. The images are uint8, the entropies [nats].
    """
    images, entropies = [], np.zeros(len(copies))
    for k, (copy, action) in enumerate(zip(copies.tolist(), actions.tolist())):
        name, pan_rad = sensors.option(action)
        image = sensors.acquire(terrains[copy], poses[k], generators[copy], name, pan_rad)
        images.append(image)
        entropies[k] = histogram_entropy(image)
    return images, entropies


def _prefixed_keys(config: dict, prefix: str) -> dict[str, str]:
    """The keys of ``config`` that start with ``prefix``, by their name without it (a sensor's field)."""
    return {key.removeprefix(prefix): key for key in config if key.startswith(prefix)}
