"""``MaskedPPOTorchRLModule``: RLlib's default PPO module that never picks a masked action (needs Ray).

It builds RLlib's default PPO networks on the ``"observation"`` part of the observations of
``agents.rllib_masking`` and adds ``log(mask)`` (clamped to RLlib's ``FLOAT_MIN``) to the action logits
in every forward pass, so sampling, the greedy action, the PPO loss and its entropy all see masked logits.
"""

from __future__ import annotations

import torch
from gymnasium import spaces
from ray.rllib.algorithms.ppo.torch.default_ppo_torch_rl_module import DefaultPPOTorchRLModule
from ray.rllib.core.columns import Columns
from ray.rllib.utils.torch_utils import FLOAT_MIN

from agents.rllib_masking import ACTION_MASK, OBSERVATION


class MaskedPPOTorchRLModule(DefaultPPOTorchRLModule):
    """RLlib's default PPO module on the ``"observation"`` part, its logits masked by ``"action_mask"``.

    Raises:
        ValueError: for observations without those two parts.
    """

    def __init__(self, *, observation_space: spaces.Dict, **kwargs):
        if not isinstance(observation_space, spaces.Dict) or set(observation_space) != {OBSERVATION, ACTION_MASK}:
            raise ValueError(
                f"MaskedPPOTorchRLModule needs observations {{{OBSERVATION!r}, {ACTION_MASK!r}}} "
                f"(agents.rllib_masking.MaskedObservations / MaskedParallelEnv), got {observation_space}"
            )
        super().__init__(observation_space=observation_space[OBSERVATION], **kwargs)  # the networks: on the Box
        self.observation_space = observation_space  # what a checkpoint rebuilds the module from

    @staticmethod
    def _split(batch: dict) -> tuple[dict, torch.Tensor]:
        """The batch with the plain observations, and the masks."""
        observations = batch[Columns.OBS]
        return {**batch, Columns.OBS: observations[OBSERVATION]}, observations[ACTION_MASK]

    @staticmethod
    def _masked(outputs: dict, mask: torch.Tensor) -> dict:
        logits = outputs[Columns.ACTION_DIST_INPUTS]
        outputs[Columns.ACTION_DIST_INPUTS] = logits + torch.clamp(torch.log(mask), min=FLOAT_MIN)
        return outputs

    def _forward(self, batch, **kwargs):
        plain, mask = self._split(batch)
        return self._masked(super()._forward(plain, **kwargs), mask)

    def _forward_train(self, batch, **kwargs):
        plain, mask = self._split(batch)
        return self._masked(super()._forward_train(plain, **kwargs), mask)

    def compute_values(self, batch, embeddings=None):
        if isinstance(batch[Columns.OBS], dict):
            batch, _ = self._split(batch)
        return super().compute_values(batch, embeddings)
