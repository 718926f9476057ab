"""One registry of every infonav env, Gymnasium and PettingZoo: id, entry point, API.

A Gymnasium entry is also registered with ``gymnasium.register``, so ``gym.make(id)`` and
``gym.make("infonav_gym:" + id)`` (what a spawned ``SubprocVecEnv`` worker does) work. A
PettingZoo parallel entry is made by ``make_env`` only. Entry points are strings
(``"module:EnvClass"``), imported when an env is made, so registering imports no env module.

Adding an env (its class declares ``episode_metrics`` and ``traits``, see ``infonav_gym.envs.traits``)::

    import infonav_gym

    infonav_gym.register("mylab/Beacon-v0", "mylab.beacon:BeaconEnv")
    env = infonav_gym.make_env("mylab/Beacon-v0", horizon=50)  # gym.make("mylab/Beacon-v0") too

Then ``evaluate("mylab/Beacon-v0", ...)`` and the benchmark's env timing run it; from the command line,
where only ``infonav_gym`` is imported, give the module that registers it on import:
``infonav evaluate --env mylab.beacon:mylab/Beacon-v0`` (``tests/test_registry.py`` does this with a toy env).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym

GYMNASIUM = "gymnasium"  # a single-agent gymnasium.Env
PARALLEL = "pettingzoo_parallel"  # a pettingzoo.ParallelEnv: every agent acts at every step
APIS = (GYMNASIUM, PARALLEL)


@dataclass(frozen=True)
class EnvEntry:
    """A registered env.

    Attributes:
        id: the env id, e.g. ``"infonav/LandmarkSelection-v0"``.
        entry_point: ``"module:EnvClass"`` (or the class itself); called with the config as keywords.
        api: ``GYMNASIUM`` or ``PARALLEL``.
        vector_entry_point: ``"module:VectorEnvClass"`` of a native ``gymnasium.vector.VectorEnv``, called with
            ``num_envs`` and the config by ``make_vector_env`` (and ``gym.make_vec`` for a Gymnasium entry); None
            for none. A parallel env's vector env steps N copies of the whole team: arrays (N, R, ...).
    """

    id: str
    entry_point: str | Callable
    api: str
    vector_entry_point: str | Callable | None = None

    def load(self) -> Callable:
        """The env class (or factory) the entry point names, imported now."""
        return _loaded(self.entry_point)

    def load_vector(self) -> Callable:
        """The native vector env class (or factory) ``vector_entry_point`` names, imported now.

        Raises:
            ValueError: if the env has none.
        """
        if self.vector_entry_point is None:
            raise ValueError(f"env {self.id!r} has no native vector env (no vector_entry_point is registered)")
        return _loaded(self.vector_entry_point)


def _loaded(entry_point: str | Callable) -> Callable:
    if not isinstance(entry_point, str):
        return entry_point
    module, _, attribute = entry_point.partition(":")
    return getattr(importlib.import_module(module), attribute)


_ENTRIES: dict[str, EnvEntry] = {}


def register(
    env_id: str, entry_point: str | Callable, api: str = GYMNASIUM, vector_entry_point: str | Callable | None = None
) -> EnvEntry:
    """Add an env to the registry (and to Gymnasium's for ``api=GYMNASIUM``); the same entry again does nothing.

    Raises:
        ValueError: for an unknown ``api``, a malformed entry point string, or an id already
            registered with another entry point or API.
    """
    if api not in APIS:
        raise ValueError(f"api of env {env_id!r} must be one of {', '.join(APIS)}, got {api!r}")
    if isinstance(entry_point, str) and entry_point.count(":") != 1:
        raise ValueError(f"entry_point of env {env_id!r} must be 'module:attribute', got {entry_point!r}")
    if isinstance(vector_entry_point, str) and vector_entry_point.count(":") != 1:
        raise ValueError(f"vector_entry_point of env {env_id!r} must be 'module:attribute', got {vector_entry_point!r}")
    entry = EnvEntry(env_id, entry_point, api, vector_entry_point)
    known = _ENTRIES.get(env_id)
    if known is not None and known != entry:
        raise ValueError(f"env id {env_id!r} is already registered as {known}; unregister it first")
    _ENTRIES[env_id] = entry
    if api == GYMNASIUM and env_id not in gym.registry:
        gym.register(id=env_id, entry_point=entry_point, vector_entry_point=vector_entry_point)
    return entry


def unregister(env_id: str) -> None:
    """Remove ``env_id`` from the registry (and from Gymnasium's); ``ValueError`` if it is not registered."""
    entry = env_entry(env_id)
    del _ENTRIES[env_id]
    if entry.api == GYMNASIUM:
        gym.registry.pop(env_id, None)


def registered_envs(api: str | None = None) -> list[EnvEntry]:
    """Every registered env (of ``api`` only, if given), in registration order."""
    return [entry for entry in _ENTRIES.values() if api is None or entry.api == api]


def env_entry(env_id: str) -> EnvEntry:
    """The entry of ``env_id``; ``ValueError`` naming it and listing the registered ids if it is unknown."""
    try:
        return _ENTRIES[env_id]
    except KeyError:
        raise ValueError(f"unknown env id {env_id!r}; choose from {', '.join(_ENTRIES)}") from None


def resolve_env_id(env_id: str) -> str:
    """``"module:id"`` (Gymnasium's prefix): import ``module``, which registers its envs, and return ``id``.

    An id without the prefix, or one registered as it is, is returned unchanged.

    Raises:
        ValueError: if the module does not import.
    """
    module, separator, name = env_id.partition(":")
    if not separator or env_id in _ENTRIES:
        return env_id
    try:
        importlib.import_module(module)
    except ImportError as error:
        raise ValueError(f"env id {env_id!r}: module {module!r} does not import ({error})") from None
    return name


def api_of(env_id: str) -> str:
    """The registry ``api`` of ``env_id``; ``GYMNASIUM`` for an id only Gymnasium knows (``CartPole-v1``)."""
    entry = _ENTRIES.get(resolve_env_id(env_id))
    return GYMNASIUM if entry is None else entry.api


def has_native_vector_env(env_id: str) -> bool:
    """Whether ``env_id`` is in this registry with a ``vector_entry_point``.

    Such a native vector env takes ``autoreset_mode=AutoresetMode.SAME_STEP``; a vector entry point outside
    the registry need not (Gymnasium's ``CartPoleVectorEnv`` does not).
    """
    try:
        entry = _ENTRIES.get(resolve_env_id(env_id))
    except ValueError:  # a module that does not import: make_env names it
        return False
    return entry is not None and entry.vector_entry_point is not None


def make_env(env_id: str, **config):
    """A new env: ``gym.make(env_id, **config)`` for a Gymnasium env, the parallel env itself for a PettingZoo one.

    ``env_id`` may carry Gymnasium's module prefix (``"mylab.beacon:mylab/Beacon-v0"``, see
    ``resolve_env_id``). A Gymnasium id outside the registry (e.g. ``CartPole-v1``) is made by ``gym.make`` too.

    Raises:
        ValueError: for an id neither registry knows (listing the infonav ids), or a bad config.
    """
    env_id = resolve_env_id(env_id)
    if api_of(env_id) == PARALLEL:
        return _ENTRIES[env_id].load()(**config)
    try:
        return gym.make(env_id, **config)
    except gym.error.Error as error:
        raise ValueError(f"unknown env id {env_id!r} ({error}); choose from {', '.join(_ENTRIES)}") from None


def make_vector_env(env_id: str, num_envs: int, **config):
    """The native vector env of ``env_id`` with ``num_envs`` copies: ``vector_entry_point(num_envs=..., **config)``.

    For a Gymnasium env that is what ``gym.make_vec(env_id, num_envs)`` returns; for a PettingZoo parallel env
    (not known to Gymnasium) it steps N copies of the whole team. ``env_id`` may carry the module prefix.

    Raises:
        ValueError: for an unknown id, an env without a native vector env, or a bad config.
    """
    return env_entry(resolve_env_id(env_id)).load_vector()(num_envs=num_envs, **config)
