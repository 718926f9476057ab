"""``infonav/SensorSelection-v0``: which sensor, camera or LADAR, to acquire and where to point it (Section IV), as
a scenario."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from infonav_gym.config import Interval, check_choice, check_config
from infonav_gym.envs.base import shared_config
from infonav_gym.envs.driver import Driver
from infonav_gym.envs.metrics import EpisodeMetric, count_where, mean_where, summed_reward_term
from infonav_gym.envs.protocol import EnvScenario, State
from infonav_gym.envs.sensor_selection.acquisition import (
    IDLE_ACTION,
    MAX_IMAGE_ENTROPY,
    SENSORS,
    ImageSensors,
    acquire_frames,
    sensor_config,
)
from infonav_gym.envs.single_view import SingleEnvView
from infonav_gym.envs.traits import EnvTraits
from infonav_gym.envs.vector_infos import Decision, decision_info
from infonav_gym.scene import SENSOR_WEDGE_LENGTH_M, PathHistory, RobotDrawing, SceneFrame
from infonav_gym.world.physics import TIME_STEP_S
from infonav_gym.world.terrain_scenario import SCENE_CONFIG, check_scene_config, terrain_loop_from_config
from infonav_gym.world.world_batch import WorldBatch

IMAGE_INFORMATION = ("entropy", "negentropy")
OPTION_FEATURES = 3
GLOBAL_FEATURES = 2 + len(SENSORS)
BANDWIDTH_BYTES = Interval(1, 10**10, integer=True, unit="bytes")  # link capacity per step, credit buffer
CONFIG_INTERVALS = {  # the allowed values of the number keys the env itself uses
    "time_step_s": TIME_STEP_S,
    "n_pan_sectors": Interval(1, 64, integer=True),
    "pan_span_rad": Interval(0.0, 2 * math.pi, unit="rad"),
    "bandwidth_bytes_per_step": BANDWIDTH_BYTES,
    "bandwidth_buffer_bytes": BANDWIDTH_BYTES,
}


@dataclass
class SensorState(State):
    """Every copy's vehicle (``worlds``), terrain and sensor noise generator; its bandwidth credit (N,) [bytes], the
    last information (N, options) [nats] and step of each acquisition option (-1: never); its last action (N,) (-1:
    none), reward (N,) [nats] and frame entropy (N,) [nats] of the step; copy 0's last frame (its image, entropy
    and heading, None without one) and its true path (``paths``, when drawing)."""

    worlds: WorldBatch
    terrains: list
    sensor_rngs: list
    credit_bytes: np.ndarray
    last_information: np.ndarray
    last_acquired_step: np.ndarray
    chosen: np.ndarray
    rewards: np.ndarray
    entropies: np.ndarray
    first_image: np.ndarray | None = None
    first_entropy: float = 0.0
    first_heading: float = 0.0
    paths: tuple[PathHistory] | None = None


class SensorSelection(EnvScenario):
    """``infonav/SensorSelection-v0`` as a scenario (spaces, reward, config: ``SensorSelectionEnv``)."""

    episode_metrics = (
        EpisodeMetric(
            "cumulative_information", "cumulative image information [nats]", summed_reward_term("image_information")
        ),
        EpisodeMetric("frames", "frames acquired [frames]", count_where(lambda info: info["sensor"] >= 0)),
        EpisodeMetric(
            "mean_frame_entropy",
            "mean frame entropy [nats]",
            mean_where("image_entropy", lambda info: info["sensor"] >= 0),
        ),
    )
    traits = EnvTraits(
        kb_per_copy=250,  # [kB] at the defaults, between peak RSS growth and traced allocations
        rewards_information_at_once=True,
        idle_actions=frozenset({IDLE_ACTION}),
        reward_terms=("image_information",),
        main_metric="cumulative_information",
        info_keys=frozenset({"sensor", "pan_rad", "image_entropy", "bandwidth_credit_bytes"}),
    )

    @classmethod
    def default_config(cls) -> dict:
        return {
            **shared_config(),
            "horizon": 100,
            "time_step_s": 0.5,  # [s]
            "speed_mps": 2.0,  # cruise speed along the route [m/s]
            "image_information": "entropy",  # "entropy" (Section IV-A) or "negentropy" (Section II)
            "n_pan_sectors": 3,  # pan directions per sensor
            "pan_span_rad": math.radians(160.0),  # from the leftmost to the rightmost pan angle [rad]
            "bandwidth_bytes_per_step": 10000,  # link capacity per step [bytes]
            "bandwidth_buffer_bytes": 40000,  # most credit the link can save up [bytes]
            **SCENE_CONFIG,  # the terrain_loop scene
            **sensor_config(),
        }

    def __init__(self, config: dict, copies: int, owner: str, render_mode: str | None):
        super().__init__(config, copies, owner, render_mode)
        check_choice(config, "image_information", IMAGE_INFORMATION, owner)
        check_config(config, owner, CONFIG_INTERVALS)
        check_scene_config(config, owner)
        self.sensors = ImageSensors(config, owner)
        n_options = self.sensors.n_options
        n_features = OPTION_FEATURES * n_options + GLOBAL_FEATURES
        high = np.full(n_features, 1.0, dtype=np.float32)
        high[1 : OPTION_FEATURES * n_options : OPTION_FEATURES] = MAX_IMAGE_ENTROPY
        self.observation_space = spaces.Box(np.zeros(n_features, dtype=np.float32), high, dtype=np.float32)
        self.action_space = spaces.Discrete(1 + n_options)

    def allocate(self, copies: int) -> SensorState:
        n_options = self.sensors.n_options
        return SensorState(
            elapsed=np.zeros(copies, dtype=int),
            worlds=WorldBatch(copies),
            **{name: [None] * copies for name in ("terrains", "sensor_rngs")},
            credit_bytes=np.zeros(copies, dtype=np.int64),
            last_information=np.zeros((copies, n_options)),
            last_acquired_step=np.full((copies, n_options), -1),
            chosen=np.full(copies, -1),
            **{name: np.zeros(copies) for name in ("rewards", "entropies")},
        )

    def initial(self, state: SensorState, rows: np.ndarray, rngs: list) -> SensorState:
        """Draw each copy's terrain loop, then spawn its sensors' generator; a full credit, nothing acquired."""
        for copy, rng in zip(rows.tolist(), rngs):
            scene = terrain_loop_from_config(rng, self.config)
            state.worlds.reset_copy(copy, scene.scenario)
            state.sensor_rngs[copy] = rng.spawn(1)[0]
            state.terrains[copy] = scene.terrain
        state.credit_bytes[rows] = self.config["bandwidth_buffer_bytes"]
        state.last_information[rows] = 0.0
        state.last_acquired_step[rows] = -1
        state.chosen[rows], state.rewards[rows], state.entropies[rows] = -1, 0.0, 0.0
        if rows[0] == 0:
            state.first_image = None
            if self.drawing:
                state.paths = (PathHistory(state.worlds.poses[0, 0, :2]),)
        return state

    def decision(self, state: SensorState, rows) -> Decision:
        """The decisions of the copies ``rows`` at their credit and last values."""
        affordable = self.sensors.option_costs <= state.credit_bytes[rows, None]
        known = state.last_acquired_step[rows] >= 0
        estimate = np.where(known, state.last_information[rows], MAX_IMAGE_ENTROPY)
        mask = np.ones((len(known), 1 + self.sensors.n_options), dtype=np.int8)
        mask[:, 1:] = affordable
        gains = np.zeros(mask.shape)
        gains[:, 1:] = np.where(affordable, estimate, 0.0)
        return Decision(mask, gains)

    def transition(self, state: SensorState, decision: Decision, action, acting) -> SensorState:
        """Acquire the chosen frames, then drive the ``acting`` copies and credit their bandwidth."""
        chosen, cfg = action[:, 0], self.config
        state.rewards, state.entropies = self._acquire(state, chosen)
        state.chosen = chosen
        stepped = np.flatnonzero(acting)
        if stepped.size:
            state.worlds.step(cfg["time_step_s"], stepped)
            credit = state.credit_bytes[stepped] + cfg["bandwidth_bytes_per_step"]
            state.credit_bytes[stepped] = np.minimum(credit, cfg["bandwidth_buffer_bytes"])
        if self.drawing and acting[0]:
            state.paths[0].append(state.worlds.poses[0, 0, :2])
        return state

    def _acquire(self, state: SensorState, chosen: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each copy acquires the frame of its chosen action (none for -1 and the idle action), paying its bytes.

        Returns:
            ``(rewards, entropies)`` (N,): the information of each copy's frame [nats] and its entropy, 0 without.
        """
        rewards, entropies = np.zeros(len(chosen)), np.zeros(len(chosen))
        state.first_image = None
        copies = np.flatnonzero(chosen > IDLE_ACTION)
        if not copies.size:
            return rewards, entropies
        options = chosen[copies] - 1
        poses = state.worlds.poses[copies, 0]
        images, entropies[copies] = acquire_frames(
            self.sensors, state.terrains, poses, state.sensor_rngs, copies, chosen[copies]
        )
        information = entropies[copies]
        if self.config["image_information"] == "negentropy":
            information = MAX_IMAGE_ENTROPY - information
        rewards[copies] = information
        state.credit_bytes[copies] -= self.sensors.option_costs[options]
        state.last_information[copies, options] = information
        state.last_acquired_step[copies, options] = state.elapsed[copies]
        if copies[0] == 0:
            state.first_image, state.first_entropy, state.first_heading = images[0], entropies[0], poses[0, 2]
        return rewards, entropies

    def reward(self, decision, action, state: SensorState) -> np.ndarray:
        """The information of each copy's frame [nats] (0 without one)."""
        return state.rewards.copy()

    def observation(self, state: SensorState, decision: Decision, rows) -> np.ndarray:
        """The observations of the copies ``rows`` (n, 3 * options + 4), float32 (see the single env)."""
        horizon, frame_bytes = self.config["horizon"], self.sensors.frame_bytes
        elapsed, last_step = state.elapsed[rows], state.last_acquired_step[rows]
        known = last_step >= 0
        age = np.where(known, (elapsed[:, None] - last_step) / horizon, 1.0)
        features = np.zeros((len(elapsed), *self.observation_space.shape))
        options = features[:, :-GLOBAL_FEATURES].reshape(len(elapsed), -1, OPTION_FEATURES)
        options[..., 0], options[..., 1], options[..., 2] = known, state.last_information[rows], np.minimum(age, 1)
        credit = state.credit_bytes[rows]
        features[:, -4] = credit / self.config["bandwidth_buffer_bytes"]
        for column, name in enumerate(SENSORS):
            features[:, -3 + column] = frame_bytes[name] <= credit
        features[:, -1] = elapsed / horizon
        return features.astype(np.float32)

    def info(self, state: SensorState, decision: Decision, rows, stepped) -> dict:
        """The decision's mask and gains, the reward term, the action taken, the sensor and pan it used, the frame's
        entropy (0 without one), the credit, the true pose and the time."""
        info = decision_info(decision, stepped, state.chosen[rows], ("image_information",), state.rewards[None, rows])
        acted = info["chosen_action"]
        sensor, pan_rad = self.sensors.options(acted)
        info.update(
            sensor=sensor,
            pan_rad=pan_rad,
            image_entropy=np.where(acted > IDLE_ACTION, state.entropies[rows], 0.0),
            bandwidth_credit_bytes=state.credit_bytes[rows].copy(),
            true_pose=state.worlds.poses[rows, 0].copy(),
            time_s=state.elapsed[rows] * self.config["time_step_s"],
        )
        return info

    def frame(self, state: SensorState, decision: Decision):
        """Copy 0 drawn: its scene, the vehicle and its path, the wedge and inset of the frame it acquired."""
        scenario, time_s = state.worlds.scenario(0), state.elapsed[0] * self.config["time_step_s"]
        caption, wedge, title = f"t = {time_s:.1f} s   ", None, ""
        if state.first_image is None:
            caption += "no frame acquired"
        else:
            sensor, pan_rad = self.sensors.option(int(state.chosen[0]))
            caption += f"{sensor} at pan {math.degrees(pan_rad):+.0f} deg: image entropy {state.first_entropy:.2f} nats"
            fov_rad = self.sensors.sensor(sensor).horizontal_fov_rad
            wedge = (state.first_heading + pan_rad, fov_rad, SENSOR_WEDGE_LENGTH_M)
            legend = "LADAR range image (dark = near, white = no return)" if sensor == "ladar" else "camera image"
            title = f"{legend} acquired this step"
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            robots=[RobotDrawing(true_pose=state.worlds.poses[0, 0].copy(), true_path=state.paths[0].points())],
            sensor_wedge=wedge,
            inset_image=state.first_image,
            inset_title=title,
            caption=caption,
        )


class SensorSelectionVectorEnv(Driver, scenario=SensorSelection):
    """N copies of ``infonav/SensorSelection-v0``, the driver bound to its scenario (``gym.make_vec``).

    Observations (N, 6 * n_pan_sectors + 4), ``info["sensor"]`` the index in ``SENSORS`` (-1: none); ``render()`` insets
    the image sub-env 0 acquired.
    """

    @property
    def sensors(self) -> ImageSensors:
        """The vehicle's LADAR and camera, their frames' bytes and the (sensor, pan) of each action."""
        return self.env_scenario.sensors

    @property
    def last_image(self) -> np.ndarray | None:
        """The uint8 image sub-env 0 acquired in the last step (LADAR: its display image), None if it acquired none."""
        image = self.state.first_image
        return None if image is None else image.copy()

    @property
    def true_poses(self) -> np.ndarray:
        """Every sub-env's true vehicle pose ``[x, y, heading]`` now (N, 3)."""
        return self.state.worlds.poses[:, 0].copy()

    def terrain(self, copy: int = 0):
        """The ``Terrain`` sub-env ``copy`` drives through in its current episode."""
        return self.state.terrains[copy]


class SensorSelectionEnv(SingleEnvView, vector_env=SensorSelectionVectorEnv):
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
    always is.

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
    ``gym.make("infonav/SensorSelection-v0", render_mode=None, **config)`` with any key of ``default_config()``.

    ## Version History
    * v0: initial version.
    """

    @property
    def last_image(self) -> np.ndarray | None:
        """The uint8 image acquired by the last step (LADAR: its display image), ``None`` if it acquired none."""
        return self.vector.last_image
