"""``cooperative_localization_v0``: the versioned PettingZoo entry points.

``parallel_env(**config)`` is the native parallel env; ``raw_env(**config)`` its AEC
conversion; ``env(**config)`` the AEC env with PettingZoo's order-enforcing wrapper
(the one to use for turn-based code). Config keys: ``CooperativeLocalizationEnv.default_config()``.
"""

from __future__ import annotations

from pettingzoo.utils.conversions import parallel_to_aec_wrapper
from pettingzoo.utils.wrappers import OrderEnforcingWrapper

from infonav_gym.multi.cooperative_localization import CooperativeLocalizationEnv

__all__ = ["env", "parallel_env", "raw_env"]


def parallel_env(render_mode: str | None = None, **config) -> CooperativeLocalizationEnv:
    """The parallel env: every robot acts at every step."""
    return CooperativeLocalizationEnv(render_mode=render_mode, **config)


def raw_env(render_mode: str | None = None, **config) -> parallel_to_aec_wrapper:
    """The AEC (agent-by-agent) conversion of ``parallel_env``, without wrappers."""
    return parallel_to_aec_wrapper(parallel_env(render_mode=render_mode, **config))


def env(render_mode: str | None = None, **config) -> OrderEnforcingWrapper:
    """The AEC env, wrapped to enforce PettingZoo's call order."""
    return OrderEnforcingWrapper(raw_env(render_mode=render_mode, **config))
