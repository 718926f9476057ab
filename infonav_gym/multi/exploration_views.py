"""What ``CooperativeExplorationEnv`` shows: observations, infos, frames, episode metrics (``ExplorationViews``)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from infonav_gym.envs.metrics import (
    EpisodeMetric,
    team_final_flag,
    team_mean_final_value,
    team_summed_reward_term,
    team_total_reward_term,
)
from infonav_gym.estimation.models import range_bearing
from infonav_gym.estimation.state import POSE_DIM
from infonav_gym.geometry import wrap_angle
from infonav_gym.information import gaussian_entropy_from_log_det
from infonav_gym.multi.team_localization import team_observations
from infonav_gym.multi.team_paths import TeamPaths
from infonav_gym.multi.team_sensing import RelativeSight
from infonav_gym.scene import SceneFrame

EXPLORATION_INFO_KEYS = frozenset(
    {"gps_available", "pose_std", "position_std_m", "pose_entropy", "position_error_m", "heading_error_rad"}
    | {"estimated_pose", "observations_left", "coverage", "lost", "failed", "success"}
)
EXPLORATION_METRICS = (
    EpisodeMetric("success_rate", "success rate", team_final_flag("success"), proportion=True),
    EpisodeMetric("failure_rate", "robot lost rate", team_final_flag("failed"), proportion=True),
    EpisodeMetric("final_coverage", "final coverage", team_mean_final_value("coverage")),
    EpisodeMetric("map_information", "team map information [nats]", team_summed_reward_term("team_map_information")),
    EpisodeMetric("pose_information", "team pose MI [nats]", team_total_reward_term("own_pose_information")),
    EpisodeMetric("episode_steps", "episode length [steps]", len),
)
LANDMARK_FEATURES = 4
TEAM_EXTRA_FEATURES = 3
_BIG = 1e4
MAP_IMAGE_PIXELS_PER_CELL = 8


class ExplorationSight(NamedTuple):
    """The payload of a decision of ``CooperativeExplorationEnv``.

    Attributes:
        relative: the relative-pose candidates (``RelativeSight``, with each robot's pose uncertainty at the prior).
        slot_valid: which observation slots each robot may choose now (R, 1 + L + R) bool.
        position_std: each robot's largest position standard deviation at the prior (R,) [m].
    """

    relative: RelativeSight
    slot_valid: np.ndarray
    position_std: np.ndarray


class ExplorationViews(TeamPaths):
    """The observations, infos and frames of ``CooperativeExplorationEnv``, a mixin of it (read-only views)."""

    @staticmethod
    def _observation_bounds(team_low, team_high, n_landmarks: int, n_cells: int) -> tuple[np.ndarray, np.ndarray]:
        """The bounds of one robot's observation: the team features, then landmarks, extras and the map."""
        low = [*team_low, *[0, 0, -1, -1] * n_landmarks, 0, 0, 0, *[0] * n_cells]
        high = [*team_high, *[1, _BIG, 1, 1] * n_landmarks, _BIG, 1, 1, *[1] * n_cells]
        return np.array(low, dtype=np.float32), np.array(high, dtype=np.float32)

    def _observations(self) -> dict:
        sight: ExplorationSight = self._decision.payload
        cfg = self.config
        n, n_landmarks = len(self.possible_agents), cfg["n_landmarks"]
        estimates = self.ekf.x.reshape(-1, POSE_DIM)
        team = team_observations(
            estimates,
            sight.relative.pose_std,
            sight.relative.pose_log_det,
            self._gps_available,
            self._elapsed_steps / self.max_cycles,
            sight.slot_valid[:, 1 + n_landmarks :],
            self._team_space,
        )
        seen = np.zeros((n, n_landmarks, 2))
        if n_landmarks:
            seen = np.array([range_bearing(estimate, self.world.landmarks) for estimate in estimates])
        budget = cfg["max_observations"]
        features = exploration_observations(
            team,
            sight.slot_valid[:, 1 : 1 + n_landmarks],
            seen,
            self.speeds_mps,
            self.observations_left / budget if budget else np.zeros(n),
            self.coverage,
            np.sqrt(self.map_variances) / self.map_model.prior_std_m,
            self._observation_spaces[self.possible_agents[0]],
        )
        return {agent: features[robot] for robot, agent in enumerate(self.agents)}

    def _infos(self) -> dict:
        sight = self._decision.payload
        estimates = self.ekf.x.reshape(-1, POSE_DIM)
        entropies = gaussian_entropy_from_log_det(sight.relative.pose_log_det, POSE_DIM)
        failed = bool(self.lost.any())
        infos = {}
        for robot, agent in enumerate(self.agents):
            true_pose, estimate = self._true_poses[robot], estimates[robot]
            infos[agent] = {
                **self._decision_info(robot),
                "pose_std": sight.relative.pose_std[robot].copy(),
                "position_std_m": float(sight.position_std[robot]),
                "pose_entropy": float(entropies[robot]),
                "position_error_m": math.dist(true_pose[:2], estimate[:2]),
                "heading_error_rad": abs(wrap_angle(float(true_pose[2] - estimate[2]))),
                "true_pose": true_pose.copy(),
                "estimated_pose": estimate.copy(),
                "time_s": self._time_s,
                "observations_left": int(self.observations_left[robot]),
                "coverage": self.coverage,
                "lost": bool(self.lost[robot]),
                "failed": failed,
                "success": self.success,
            }
        return infos

    # ------------------------------------------------------------------ rendering

    def _scene_frame(self):
        scenario = self.world.scenario
        side = self.config["map_cells_per_side"]
        known = 1.0 - np.sqrt(self.map_variances) / self.map_model.prior_std_m
        image = np.kron(np.flipud(known.reshape(side, side)), np.ones((MAP_IMAGE_PIXELS_PER_CELL,) * 2))
        return SceneFrame(
            bounds=scenario.bounds,
            walls=scenario.walls,
            obstacles=scenario.obstacles,
            landmarks=self.world.landmarks,
            robots=self._robot_drawings(),
            observations=list(self._observed_pairs),
            landmark_observations=list(self._observed_landmarks),
            gps_denied_zones=scenario.gps_denied_zones,
            inset_image=np.round(255 * image).astype(np.uint8),
            inset_title=f"terrain map (white: known), coverage {self.coverage:.0%}",
            caption=f"t = {self._time_s:.0f} s   {len(self._observed_pairs)} teammate and "
            f"{len(self._observed_landmarks)} landmark observations this step",
        )


def exploration_observations(
    team, landmark_valid, landmarks_seen, speeds_mps, budget_left, coverage, cell_std, space
) -> np.ndarray:
    """Every robot's observation (see ``CooperativeExplorationEnv``), float32 clipped to ``space``, for R robots.

    Any leading dimensions (B...) are batch dimensions (the vector env's copies).

    Args:
        team: the ``team_observations`` part (B..., R, 10 + 5 R).
        landmark_valid: whether observing each landmark is valid now (B..., R, L).
        landmarks_seen: each landmark's range [m] and bearing [rad] from each robot's estimate (B..., R, L, 2).
        speeds_mps: each robot's speed (R,) [m/s].
        budget_left: each robot's sensing budget left, a fraction (B..., R).
        coverage: the team's coverage (B...) (a number for one team).
        cell_std: each cell's height std left, a fraction of the prior's (B..., G).
        space: one robot's observation space.
    """
    lead, n = np.shape(team)[:-2], np.shape(team)[-2]
    landmarks = np.zeros((*lead, n, np.shape(landmark_valid)[-1], LANDMARK_FEATURES))
    landmarks[..., 0] = landmark_valid
    landmarks[..., 1] = landmarks_seen[..., 0]
    landmarks[..., 2], landmarks[..., 3] = np.cos(landmarks_seen[..., 1]), np.sin(landmarks_seen[..., 1])
    extras = np.stack(
        np.broadcast_arrays(speeds_mps, budget_left, np.asarray(coverage, dtype=float)[..., None]), axis=-1
    )
    cells = np.broadcast_to(np.asarray(cell_std)[..., None, :], (*lead, n, np.shape(cell_std)[-1]))
    features = np.concatenate([team, landmarks.reshape(*lead, n, -1), extras, cells], axis=-1).astype(np.float32)
    return np.clip(features, space.low, space.high, out=features)
