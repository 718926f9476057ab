"""``infonav/SensorSelection-v0``: which sensor, camera or LADAR, to acquire and where to point it (Section IV)."""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from infonav_gym.config import Interval, check_choice, check_config, from_config
from infonav_gym.envs.base import Decision, InfoNavEnv
from infonav_gym.envs.metrics import EpisodeMetric, count_where, mean_where, summed_reward_term
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.information import histogram_entropy
from infonav_gym.scene import SENSOR_WEDGE_LENGTH_M, PathHistory, RobotDrawing, SceneFrame
from infonav_gym.sensors.camera import Camera
from infonav_gym.sensors.ladar import Ladar, to_display_image
from infonav_gym.world.terrain_scenario import SCENE_CONFIG, check_scene_config, terrain_loop_from_config
from infonav_gym.world.world import TIME_STEP_S, World

SENSORS = ("ladar", "camera")
IMAGE_INFORMATION = ("entropy", "negentropy")
IDLE_ACTION = 0
MAX_IMAGE_ENTROPY = math.log(256)  # entropy of a uniform 256-level histogram [nats]
OPTION_FEATURES = 3
GLOBAL_FEATURES = 2 + len(SENSORS)
_BYTES_PER_PIXEL = {"ladar": 2, "camera": 1}  # 16-bit ranges, 8-bit gray levels
BANDWIDTH_BYTES = Interval(1, 10**10, integer=True, unit="bytes")  # link capacity per step, credit buffer
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "time_step_s": TIME_STEP_S,
    "n_pan_sectors": Interval(1, 64, integer=True),
    "pan_span_rad": Interval(0.0, 2 * math.pi, unit="rad"),
    "bandwidth_bytes_per_step": BANDWIDTH_BYTES,
    "bandwidth_buffer_bytes": BANDWIDTH_BYTES,
}


class SensorSelectionEnv(InfoNavEnv):
    """A vehicle drives a loop through rugged terrain; each step it may acquire one image, chosen for its information.

    ## Description
    The vehicle carries a LADAR (a 32 x 180 range image, 20 x 80 degrees, shown the
    paper's way: dark = near) and a grayscale camera (120 x 160, 60 degrees) on a pan-tilt
    platform, and drives a closed route (Pymunk) through a random 2.5D scene of hills,
    trees, rocks and buildings. Each step the agent either acquires one image, choosing
    the sensor and the pan direction, or waits. Frames use a radio link of limited
    bandwidth: each step adds ``bandwidth_bytes_per_step`` to a credit capped at
    ``bandwidth_buffer_bytes``, and a frame costs its size (LADAR 2 bytes per pixel,
    camera 1), so LADAR and camera frames cost differently.

    The information of an image is the entropy of its 256-bin gray-level histogram (the
    paper's Eqs. 4-5). It is known only once the image is acquired, so the agent sees, per
    (sensor, direction), the last value it measured and how old it is; the scene changes
    as the vehicle moves. ``info["action_information_gain"]`` is the greedy estimate: the
    last known value, optimistic (``ln 256``, the largest possible) for a (sensor,
    direction) never acquired, 0 for waiting and for unaffordable frames.

    Which convention of "information" to reward is a config choice because the paper is
    inconsistent: Section II defines information as the negative of entropy, while Section
    IV-A calls the higher-entropy LADAR images the more informative ones. The default,
    ``image_information="entropy"``, follows Section IV-A, where images are compared: a
    histogram spread over many gray levels means many distinguishable structures in the
    scene, and the image is worth more. ``"negentropy"`` rewards ``ln 256 - H`` (the
    negative entropy shifted to be >= 0, highest for a featureless image), Section II's
    convention.

    ## Action Space
    ``Discrete(1 + 2 * n_pan_sectors)``: 0 waits (acquires nothing); ``1 + s * n_pan_sectors
    + p`` acquires sensor ``s`` (0 LADAR, 1 camera) panned to sector ``p``, the pan angles
    spread evenly over ``pan_span_rad`` from left (``p = 0``) to right. An acquisition is
    valid when the bandwidth credit covers the frame (``info["action_mask"]``); waiting
    always is. A masked action is a no-op with reward 0 by default (``invalid_action="noop"``)
    or raises ``ValueError`` with ``invalid_action="raise"``. ``action_masks()`` gives the mask as
    bool, for ``MaskablePPO``.

    ## Observation Space
    ``Box(float32, (3 * 2 * n_pan_sectors + 4,))``: per (sensor, sector), in action order:
    whether it was ever acquired, the last information value [nats] (0 if never), and its
    age as a fraction of the horizon (1 if never or older than the horizon); then the
    bandwidth credit as a fraction of the buffer, whether a LADAR frame and a camera frame
    are affordable now, and the elapsed fraction of the horizon.

    ## Rewards
    The information of the acquired image [nats]: its histogram entropy ``H``, or
    ``ln 256 - H`` with ``image_information="negentropy"``; 0 when waiting.

    ## Starting State
    The vehicle at the start of its route with a full bandwidth buffer; nothing acquired yet.

    ## Episode End
    Truncated after ``horizon`` steps; never terminated.

    ## Arguments
    ``gym.make("infonav/SensorSelection-v0", render_mode=None, **config)`` with any key of
    ``default_config()``; an unknown key raises ``ValueError`` naming it.

    ## Version History
    * v0: initial version.
    """

    episode_metrics = (
        EpisodeMetric(
            "cumulative_information", "cumulative image information [nats]", summed_reward_term("image_information")
        ),
        EpisodeMetric("frames", "frames acquired", count_where(lambda info: info["sensor"] != "none")),
        EpisodeMetric(
            "mean_frame_entropy",
            "mean frame entropy [nats]",
            mean_where("image_entropy", lambda info: info["sensor"] != "none"),
        ),
    )
    traits = EnvTraits(
        rewards_information_at_once=True,
        idle_actions=frozenset({IDLE_ACTION}),
        reward_terms=("image_information",),
        info_keys=frozenset({"sensor", "pan_rad", "image_entropy", "bandwidth_credit_bytes"}),
    )

    @classmethod
    def default_config(cls) -> dict:
        ladar, camera = Ladar(), Camera()
        return {
            **super().default_config(),
            "horizon": 100,
            "time_step_s": 0.5,  # [s]
            "speed_mps": 2.0,  # cruise speed along the route [m/s]
            "image_information": "entropy",  # "entropy" (Section IV-A) or "negentropy" (Section II)
            "n_pan_sectors": 3,  # pan directions per sensor
            "pan_span_rad": math.radians(160.0),  # from the leftmost to the rightmost pan angle [rad]
            "bandwidth_bytes_per_step": 10000,  # link capacity per step [bytes]
            "bandwidth_buffer_bytes": 40000,  # most credit the link can save up [bytes]
            **SCENE_CONFIG,  # the terrain_loop scene
            "ladar_rows": ladar.rows,
            "ladar_columns": ladar.columns,
            "ladar_vertical_fov_rad": ladar.vertical_fov_rad,
            "ladar_horizontal_fov_rad": ladar.horizontal_fov_rad,
            "ladar_range_std_m": ladar.range_std_m,
            "ladar_max_range_m": ladar.max_range_m,
            "camera_rows": camera.rows,
            "camera_columns": camera.columns,
            "camera_horizontal_fov_rad": camera.horizontal_fov_rad,
            "camera_noise_std": camera.noise_std,  # [gray levels]
        }

    def __init__(self, render_mode: str | None = None, **config):
        super().__init__(render_mode=render_mode, **config)
        cfg, owner = self.config, type(self).__name__
        check_choice(cfg, "image_information", IMAGE_INFORMATION, owner)
        check_config(cfg, owner, CONFIG_INTERVALS)
        check_scene_config(cfg, owner)
        self.ladar = from_config(Ladar, cfg, _prefixed_keys(cfg, "ladar_"), owner)
        self.camera = from_config(Camera, cfg, _prefixed_keys(cfg, "camera_"), owner)
        self.frame_bytes = {
            "ladar": _BYTES_PER_PIXEL["ladar"] * self.ladar.rows * self.ladar.columns,
            "camera": _BYTES_PER_PIXEL["camera"] * self.camera.rows * self.camera.columns,
        }
        if cfg["bandwidth_buffer_bytes"] < min(self.frame_bytes.values()):
            raise ValueError(
                f"config key 'bandwidth_buffer_bytes' of {owner} must hold at least one frame "
                f"({min(self.frame_bytes.values())} bytes), got {cfg['bandwidth_buffer_bytes']}"
            )
        n_pan = cfg["n_pan_sectors"]
        self.pan_angles_rad = np.linspace(0.5, -0.5, n_pan) * cfg["pan_span_rad"] if n_pan > 1 else np.zeros(1)
        self.n_options = len(SENSORS) * n_pan
        self.action_space = spaces.Discrete(1 + self.n_options)
        n_features = OPTION_FEATURES * self.n_options + GLOBAL_FEATURES
        high = np.full(n_features, 1.0, dtype=np.float32)
        high[1 : OPTION_FEATURES * self.n_options : OPTION_FEATURES] = MAX_IMAGE_ENTROPY
        self.observation_space = spaces.Box(np.zeros(n_features, dtype=np.float32), high, dtype=np.float32)
        self.world = World()
        self._option_costs = np.repeat([self.frame_bytes[name] for name in SENSORS], n_pan)

    def _reset_episode(self) -> None:
        cfg = self.config
        scene = terrain_loop_from_config(self.np_random, cfg)
        self.terrain = scene.terrain
        self.world.reset(scene.scenario)
        self._sensor_rng = self.np_random.spawn(1)[0]
        self._true_pose = self.world.pose
        self._true_path = PathHistory(self._true_pose[:2])
        self._credit_bytes = cfg["bandwidth_buffer_bytes"]
        self._last_information = np.zeros(self.n_options)
        self._last_acquired_step = np.full(self.n_options, -1)
        self._last_image = None
        self._last_entropy = None

    @property
    def last_image(self) -> np.ndarray | None:
        """The uint8 image acquired by the last step (LADAR: its display image), ``None`` if it acquired none."""
        return None if self._last_image is None else self._last_image.copy()

    def option(self, action: int) -> tuple[str, float]:
        """The ``(sensor name, pan angle [rad])`` that acquisition ``action`` (>= 1) uses."""
        sensor, sector = divmod(action - 1, len(self.pan_angles_rad))
        return SENSORS[sensor], float(self.pan_angles_rad[sector])

    def acquire(self, sensor: str, pan_rad: float) -> np.ndarray:
        """A uint8 image from ``sensor`` panned by ``pan_rad`` at the current true pose (LADAR: the display image)."""
        if sensor == "ladar":
            return to_display_image(self.ladar.scan(self.terrain, self._true_pose, self._sensor_rng, pan_rad=pan_rad))
        return self.camera.capture(self.terrain, self._true_pose, self._sensor_rng, pan_rad=pan_rad)

    def _next_decision(self) -> Decision:
        affordable = self._option_costs <= self._credit_bytes
        mask = np.concatenate([[1], affordable]).astype(np.int8)
        known = self._last_acquired_step >= 0
        estimate = np.where(known, self._last_information, MAX_IMAGE_ENTROPY)
        gains = np.concatenate([[0.0], np.where(affordable, estimate, 0.0)])
        return Decision(mask, gains)

    def _apply_action(self, action: int | None, decision: Decision) -> dict:
        self._last_image = self._last_entropy = None
        if action is None or action == IDLE_ACTION:
            return {"image_information": 0.0}
        sensor, pan_rad = self.option(action)
        self._acquired_heading = float(self._true_pose[2])
        self._last_image = self.acquire(sensor, pan_rad)
        self._last_entropy = histogram_entropy(self._last_image)
        information = self._last_entropy
        if self.config["image_information"] == "negentropy":
            information = MAX_IMAGE_ENTROPY - self._last_entropy
        self._credit_bytes -= self.frame_bytes[sensor]
        self._last_information[action - 1] = information
        self._last_acquired_step[action - 1] = self._elapsed_steps
        return {"image_information": information}

    def _advance(self) -> None:
        cfg = self.config
        self.world.step(cfg["time_step_s"])
        self._true_pose = self.world.pose
        self._true_path.append(self._true_pose[:2])
        self._credit_bytes = min(self._credit_bytes + cfg["bandwidth_bytes_per_step"], cfg["bandwidth_buffer_bytes"])

    def _observation(self) -> np.ndarray:
        horizon = self.config["horizon"]
        known = self._last_acquired_step >= 0
        age = np.where(known, (self._elapsed_steps - self._last_acquired_step) / horizon, 1.0)
        options = np.stack([known, self._last_information, np.minimum(age, 1.0)], axis=1)
        affordable = [self.frame_bytes[name] <= self._credit_bytes for name in SENSORS]
        credit = self._credit_bytes / self.config["bandwidth_buffer_bytes"]
        features = np.concatenate([options.ravel(), [credit], affordable, [self._elapsed_steps / horizon]])
        return features.astype(np.float32)

    def _extra_info(self) -> dict:
        acquired = self._chosen_action not in (None, IDLE_ACTION)
        sensor, pan_rad = self.option(self._chosen_action) if acquired else ("none", 0.0)
        return {
            "sensor": sensor,
            "pan_rad": pan_rad,
            "image_entropy": self._last_entropy if acquired else 0.0,
            "bandwidth_credit_bytes": self._credit_bytes,
            "true_pose": self._true_pose.copy(),
            "time_s": self._elapsed_steps * self.config["time_step_s"],
        }

    def _scene_frame(self):
        scenario = self.world.scenario
        caption = f"t = {self._elapsed_steps * self.config['time_step_s']:.1f} s   "
        wedge = None
        if self._last_entropy is None:
            caption += "no frame acquired"
        else:
            sensor, pan_rad = self.option(self._chosen_action)
            caption += f"{sensor} at pan {math.degrees(pan_rad):+.0f} deg: image entropy {self._last_entropy:.2f} nats"
            wedge = (self._acquired_heading + pan_rad, getattr(self, sensor).horizontal_fov_rad, SENSOR_WEDGE_LENGTH_M)
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            robots=[RobotDrawing(true_pose=self._true_pose, true_path=self._true_path.points())],
            sensor_wedge=wedge,
            inset_image=self._last_image,
            inset_title=self._inset_title(),
            caption=caption,
        )

    def _inset_title(self) -> str:
        """What the inset shows: the image acquired this step."""
        if self._last_image is None:
            return ""
        sensor = self.option(self._chosen_action)[0]
        legend = "LADAR range image (dark = near, white = no return)" if sensor == "ladar" else "camera image"
        return f"{legend} acquired this step"


def _prefixed_keys(config: dict, prefix: str) -> dict[str, str]:
    """The keys of ``config`` that start with ``prefix``, by their name without it (a sensor's field)."""
    return {key.removeprefix(prefix): key for key in config if key.startswith(prefix)}
