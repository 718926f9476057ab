"""``InfonavTorchEnv``: TorchRL's view of a native vector env, as VMAS gives one: batch size N (the copies), the
team's robots one agent group (``"agents"``, shape (N, R)) with their observations, action masks and rewards;
a single-agent env's at the root (``"observation"``, ``"action_mask"``, ``"action"``, ``"reward"``).

Actions are categorical (an index per robot). A copy whose episode ended is restarted by TorchRL's partial reset
(``"_reset"``): the vector env runs with ``SAME_STEP`` autoreset, so the step that ends an episode gives its last
observation to ``"next"`` and keeps the new episode's first, which the reset then hands out.
"""

from __future__ import annotations

import numpy as np
import torch
from gymnasium.vector import AutoresetMode
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Binary, Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from infonav_gym.registry import PARALLEL, api_of, make_vector_env

GROUP = "agents"  # the team's one agent group
DONE_KEYS = ("done", "terminated", "truncated")


class InfonavTorchEnv(EnvBase):
    """``num_envs`` copies of ``env_id`` (any registered env; ``config`` its keywords) as a TorchRL ``EnvBase``;
    ``seed`` seeds copy ``i`` with ``seed + i`` at the first reset (``set_seed`` before it changes that)."""

    batch_locked = True

    def __init__(self, env_id: str, num_envs: int = 1, seed: int | None = 0, device="cpu", **config):
        super().__init__(device=device, batch_size=torch.Size([num_envs]))
        self.env_id, self.team = env_id, api_of(env_id) == PARALLEL
        self.vector = make_vector_env(env_id, num_envs, autoreset_mode=AutoresetMode.SAME_STEP, **config)
        self.agent_names = list(self.vector.agents) if self.team else []
        self._seed, self._first = seed, None  # the observations and masks kept for the copies that ended
        self._ended = np.zeros(num_envs, dtype=bool)  # which ended in the last step
        space = self.vector.single_observation_space
        n_actions = int(self.vector.single_action_space.n)
        shape = torch.Size([num_envs, len(self.agent_names)] if self.team else [num_envs])
        observation = Bounded(
            torch.as_tensor(np.broadcast_to(space.low, (*shape, *space.shape)).copy()),
            torch.as_tensor(np.broadcast_to(space.high, (*shape, *space.shape)).copy()),
            shape=(*shape, *space.shape),
            dtype=torch.float32,
            device=device,
        )
        agent = {
            "observation": observation,
            "action_mask": Binary(n=n_actions, shape=(*shape, n_actions), dtype=torch.bool, device=device),
        }
        action = {"action": Categorical(n=n_actions, shape=shape, dtype=torch.int64, device=device)}
        reward = {"reward": Unbounded(shape=(*shape, 1), device=device)}
        if self.team:
            agent, action, reward = (
                {GROUP: Composite(part, shape=shape, device=device)} for part in (agent, action, reward)
            )
        self.observation_spec = Composite(agent, shape=self.batch_size, device=device)
        self.action_spec = Composite(action, shape=self.batch_size, device=device)
        self.reward_spec = Composite(reward, shape=self.batch_size, device=device)
        flag = Categorical(n=2, shape=(num_envs, 1), dtype=torch.bool, device=device)
        self.done_spec = Composite({key: flag.clone() for key in DONE_KEYS}, shape=self.batch_size, device=device)

    @property
    def group_map(self) -> dict[str, list[str]]:
        """The agent groups (a team env's robots, in order): what BenchMARL and TorchRL's MARL modules read."""
        return {GROUP: self.agent_names} if self.team else {}

    def _outputs(self, observation: np.ndarray, masks: np.ndarray, flags: dict, rewards=None) -> TensorDict:
        """The tensordict of the copies' ``observation``, ``masks``, done ``flags`` and ``rewards`` (a team's
        grouped, batch (N, R))."""
        agent = {
            "observation": torch.from_numpy(np.asarray(observation, dtype=np.float32)),
            "action_mask": torch.from_numpy(masks),
        }
        if rewards is not None:
            agent["reward"] = torch.as_tensor(rewards, dtype=torch.float32, device=self.device).unsqueeze(-1)
        if self.team:
            shape = (*self.batch_size, len(self.agent_names))
            agent = {GROUP: TensorDict(agent, batch_size=shape, device=self.device)}
        return TensorDict({**agent, **flags}, batch_size=self.batch_size, device=self.device)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        """The copies ``"_reset"`` marks from the starts their last step kept; every copy anew without a mark (the
        first time with the seeds), or when it marks one whose episode goes on. ``ValueError`` for a mark of only
        some copies, one of which goes on (the native vector env restarts a copy only when it ends)."""
        reset = None if tensordict is None else tensordict.get("_reset", None)
        marked = None if reset is None else reset.reshape(-1).cpu().numpy()
        if self._first is None or marked is None or (marked & ~self._ended).any():
            if marked is not None and self._first is not None and not marked.all():
                raise ValueError(f"{self.env_id}: only copies whose episode ended restart alone; reset them all")
            observation, _ = self.vector.reset(seed=self._seed if self._first is None else None)
            self._first = (observation, self.vector.action_masks())
        self._ended = np.zeros(self.vector.num_envs, dtype=bool)
        flags = {key: torch.zeros((*self.batch_size, 1), dtype=torch.bool, device=self.device) for key in DONE_KEYS}
        return self._outputs(*self._first, flags)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        """One step of every copy; an ended copy's last observation, its next start kept for ``_reset``."""
        actions = tensordict.get((GROUP, "action") if self.team else "action").cpu().numpy()
        observation, reward, terminated, truncated, info = self.vector.step(actions)
        masks = self.vector.action_masks()
        self._first = (observation, masks)  # fresh arrays each step: kept as they are
        ended = self._ended = np.asarray(info.get("_final_obs", np.zeros(self.vector.num_envs, dtype=bool)))
        if ended.any():
            observation = observation.copy()
            observation[ended] = np.stack(list(info["final_obs"][ended]))
            masks = masks.copy()
            masks[ended] = True  # an ended episode takes no action: every one is allowed
        if self.team:
            terminated, truncated = terminated[:, 0], truncated[:, 0]
        flags = {
            "terminated": torch.as_tensor(terminated, device=self.device).reshape(-1, 1),
            "truncated": torch.as_tensor(truncated, device=self.device).reshape(-1, 1),
        }
        flags["done"] = flags["terminated"] | flags["truncated"]
        return self._outputs(observation, masks, flags, reward)

    def _set_seed(self, seed: int | None):
        """The seed of the next full reset (copy ``i``: ``seed + i``)."""
        self._seed, self._first = seed, None

    def close(self, *, raise_if_closed: bool = True):
        self.vector.close()
        super().close(raise_if_closed=raise_if_closed)
