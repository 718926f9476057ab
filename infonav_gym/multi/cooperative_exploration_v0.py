"""``cooperative_exploration_v0``: the versioned PettingZoo entry points (``pettingzoo_entry_points``).

``parallel_env(**config)`` is the native parallel env; ``raw_env(**config)`` its AEC
conversion; ``env(**config)`` the AEC env with PettingZoo's order-enforcing wrapper.
Config keys: ``CooperativeExplorationEnv.default_config()``.
"""

from __future__ import annotations

from infonav_gym.envs.cooperative_exploration import CooperativeExplorationEnv
from infonav_gym.envs.parallel_view import pettingzoo_entry_points

__all__ = ["env", "parallel_env", "raw_env"]

parallel_env, raw_env, env = pettingzoo_entry_points(CooperativeExplorationEnv)
