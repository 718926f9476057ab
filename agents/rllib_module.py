"""``MaskedPPOTorchRLModule``: RLlib's default PPO module that never picks a masked action (needs Ray).

``log(mask)`` is added to the logits of every forward pass; with ``model_config["normalize_observations"]`` the
``"observation"`` part is normalized as by ``VecNormalize``, its running statistics kept in the module's buffers.
"""

from __future__ import annotations

import torch
from gymnasium import spaces
from ray.rllib.algorithms.ppo.torch.default_ppo_torch_rl_module import DefaultPPOTorchRLModule
from ray.rllib.core.columns import Columns
from ray.rllib.utils.torch_utils import FLOAT_MIN

from agents.rllib_masking import ACTION_MASK, NORMALIZE_OBSERVATIONS, OBSERVATION

NORMALIZED_CLIP = 10.0  # as VecNormalize's clip_obs
VARIANCE_EPSILON = 1e-8


class MaskedPPOTorchRLModule(DefaultPPOTorchRLModule):
    """RLlib's default PPO module on the ``"observation"`` part, its logits masked by the ``"action_mask"`` part."""

    def __init__(self, *, observation_space: spaces.Dict, **kwargs):
        if not isinstance(observation_space, spaces.Dict) or set(observation_space) != {OBSERVATION, ACTION_MASK}:
            raise ValueError(
                f"MaskedPPOTorchRLModule needs observations {{{OBSERVATION!r}, {ACTION_MASK!r}}} "
                f"(agents.rllib_masking, agents.rllib_team_env), got {observation_space}"
            )
        super().__init__(observation_space=observation_space[OBSERVATION], **kwargs)  # the networks: on the Box
        self.observation_space = observation_space  # what a checkpoint rebuilds the module from
        self.normalizes = bool((self.model_config or {}).get(NORMALIZE_OBSERVATIONS, False))
        if self.normalizes:
            size = observation_space[OBSERVATION].shape[0]
            self.register_buffer("observation_mean", torch.zeros(size, dtype=torch.float64))
            self.register_buffer("observation_var", torch.ones(size, dtype=torch.float64))
            self.register_buffer("observation_count", torch.tensor(VARIANCE_EPSILON, dtype=torch.float64))

    def _split(self, batch: dict) -> tuple[dict, torch.Tensor]:
        """The batch with the plain (normalized) observations, and the masks."""
        observations = batch[Columns.OBS]
        plain = observations[OBSERVATION]
        if self.normalizes:
            scaled = (plain.double() - self.observation_mean) / torch.sqrt(self.observation_var + VARIANCE_EPSILON)
            plain = torch.clamp(scaled, -NORMALIZED_CLIP, NORMALIZED_CLIP).to(plain.dtype)
        return {**batch, Columns.OBS: plain}, observations[ACTION_MASK]

    @torch.no_grad()
    def update_normalization(self, observations: torch.Tensor) -> None:
        """Merge a batch of plain observations (B, n) into the running mean and variance (Chan et al.'s update)."""
        batch = observations.reshape(-1, observations.shape[-1]).double()
        count = batch.shape[0]
        if not self.normalizes or count == 0:
            return
        mean, var = batch.mean(dim=0), batch.var(dim=0, unbiased=False)
        total = self.observation_count + count
        delta = mean - self.observation_mean
        previous = self.observation_count
        m2 = self.observation_var * previous + var * count + delta**2 * previous * count / total
        self.observation_mean += delta * count / total
        self.observation_var.copy_(m2 / total)
        self.observation_count.copy_(total)

    @staticmethod
    def _masked(outputs: dict, mask: torch.Tensor) -> dict:
        logits = outputs[Columns.ACTION_DIST_INPUTS]
        outputs[Columns.ACTION_DIST_INPUTS] = logits + torch.clamp(torch.log(mask), min=FLOAT_MIN)
        return outputs

    def _forward(self, batch, **kwargs):
        plain, mask = self._split(batch)
        return self._masked(super()._forward(plain, **kwargs), mask)

    def _forward_train(self, batch, **kwargs):
        self.update_normalization(batch[Columns.OBS][OBSERVATION])
        plain, mask = self._split(batch)
        return self._masked(super()._forward_train(plain, **kwargs), mask)

    def compute_values(self, batch, embeddings=None):
        if isinstance(batch[Columns.OBS], dict):
            batch, _ = self._split(batch)
        return super().compute_values(batch, embeddings)
