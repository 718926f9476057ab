"""Keep the best policy of a training run, judged on validation seeds by the main metric (rl-zoo's EvalCallback)."""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from sb3_contrib.common.maskable.utils import get_action_masks, is_masking_supported
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecEnv

from agents.learning_curve import METRIC_KEY, VALIDATION_CSV

VALIDATION_SEEDS = 2_000_000  # validation episodes are played from this seed on (plus the training seed)
BEST_DIR = "best"  # OUTPUT/best/model.zip: the policy best on the validation seeds
IMPROVEMENT = 1e-9  # relative: a smaller gain over the best so far is a tie, which keeps the earlier policy


def validation_metrics(model, vec_env: VecEnv, episodes: int, seed: int, normalization=None) -> np.ndarray:
    """The main metric of each of ``episodes`` episodes, seeds ``seed ..``, played by ``model``'s deterministic policy.

    ``vec_env`` holds ``episodes`` copies (of ``num_envs // episodes`` robot slots each) reporting ``METRIC_KEY``; only
    each copy's first episode counts. ``normalization``: the training ``VecNormalize``.
    """
    slots = vec_env.num_envs // episodes
    vec_env.seed(seed)
    observations = vec_env.reset()
    metrics = np.full(episodes, math.nan)
    ended = np.zeros(episodes, dtype=bool)
    masked = is_masking_supported(vec_env)
    while not ended.all():
        seen = normalization.normalize_obs(observations) if normalization is not None else observations
        masks = {"action_masks": get_action_masks(vec_env)} if masked else {}
        actions, _ = model.predict(seen, deterministic=True, **masks)
        observations, _, dones, infos = vec_env.step(actions)
        for slot in np.flatnonzero(dones):
            episode = slot // slots
            if not ended[episode]:
                ended[episode], metrics[episode] = True, infos[slot][METRIC_KEY]
    return metrics


class ValidationCallback(BaseCallback):
    """Validates the policy every ``every`` env steps (checked at each rollout's end), at the start and at the end.

    ``vec_env``: ``episodes`` copies (see ``validation_metrics``); ``seed``: the first validation seed; ``directory``
    holds ``validation.csv`` and ``best/``; ``save`` writes a model into a directory (``ppo.save_policy``);
    ``stop_at``: stop training once a validation's mean reaches it (rl-zoo's ``StopTrainingOnRewardThreshold``).
    """

    def __init__(
        self,
        vec_env: VecEnv,
        episodes: int,
        every: int,
        seed: int,
        directory: Path,
        save: Callable[..., Path],
        stop_at: float | None = None,
    ):
        super().__init__()
        self.vec_env, self.episodes, self.every, self.seed, self.save = vec_env, episodes, every, seed, save
        self.directory = Path(directory)
        self.path = self.directory / VALIDATION_CSV
        self.best_metric, self.best_steps, self.validated_at = math.nan, None, None
        self.stop_at, self.stopped_at = stop_at, None
        self.seconds = 0.0

    def _on_training_start(self) -> None:
        self.directory.mkdir(parents=True, exist_ok=True)
        with self.path.open("w", newline="") as file:
            csv.writer(file).writerow(["steps", "mean_metric", "episodes", "kept"])
        self._validate()

    def _on_step(self) -> bool:
        return self.stopped_at is None

    def _on_rollout_end(self) -> None:
        if self.num_timesteps - self.validated_at >= self.every:
            self._validate()

    def _on_training_end(self) -> None:
        if self.num_timesteps != self.validated_at:
            self._validate()

    def close(self) -> None:
        """Close the validation copies (``train`` does, after training or Ctrl-C)."""
        self.vec_env.close()

    def _validate(self) -> None:
        start = time.perf_counter()
        normalization = self.model.get_vec_normalize_env()
        mean = float(np.mean(validation_metrics(self.model, self.vec_env, self.episodes, self.seed, normalization)))
        self.validated_at = self.num_timesteps
        kept = self.best_steps is None or mean - self.best_metric > IMPROVEMENT * max(abs(self.best_metric), 1.0)
        if kept:
            self.best_metric, self.best_steps = mean, self.num_timesteps
            self.save(self.model, self.directory / BEST_DIR)
        with self.path.open("a", newline="") as file:
            csv.writer(file).writerow([self.num_timesteps, repr(mean), self.episodes, int(kept)])
        if self.stop_at is not None and mean >= self.stop_at and self.stopped_at is None:
            self.stopped_at = self.num_timesteps  # SB3 stops at the next step: one more update, kept in model.zip
        self.seconds += time.perf_counter() - start

    def record(self) -> dict:
        """What train.json keeps of the validations."""
        return {
            "episodes": self.episodes,
            "seeds": f"{self.seed}..{self.seed + self.episodes - 1}",
            "every": self.every,
            "best_steps": self.best_steps,
            "best_metric": self.best_metric,
            "csv": str(self.path),
            "best": str(self.directory / BEST_DIR),
            "seconds": self.seconds,
            "stop_at": self.stop_at,
            "stopped_at": self.stopped_at,
        }
