"""One registry of every infonav env, Gymnasium and PettingZoo: id, entry point, API.

A Gymnasium entry is registered with ``gymnasium.register`` too, so ``gym.make("infonav_gym:" + id)`` works in a
spawned worker; a PettingZoo parallel entry is made by ``make_env``. String entry points (``"module:EnvClass"``)
are imported when an env is made. An env of yours (its class declares ``episode_metrics`` and ``traits``):
``infonav_gym.register("mylab/Beacon-v0", "mylab.beacon:BeaconEnv")``; on the command line name the module that
registers it: ``infonav evaluate --env mylab.beacon:mylab/Beacon-v0``.
"""

from __future__ import annotations

import importlib
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym

from infonav_gym.datasets import DatasetNotFound

GYMNASIUM = "gymnasium"  # a single-agent gymnasium.Env
PARALLEL = "pettingzoo_parallel"  # a pettingzoo.ParallelEnv: every agent acts at every step
APIS = (GYMNASIUM, PARALLEL)


@dataclass(frozen=True)
class EnvEntry:
    """A registered env: id, ``"module:EnvClass"`` (or the class) called with the config, ``GYMNASIUM`` or
    ``PARALLEL``, and its native vector env's entry point or None (a parallel env's steps N copies of the team)."""

    id: str
    entry_point: str | Callable
    api: str
    vector_entry_point: str | Callable | None = None

    def load(self) -> Callable:
        """The env class (or factory) the entry point names, imported now."""
        return _loaded(self.entry_point)

    def load_vector(self) -> Callable:
        """The native vector env class (or factory) ``vector_entry_point`` names, imported; ``ValueError`` if none."""
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

    ``ValueError`` for an unknown ``api``, a malformed entry point, or an id registered otherwise.
    """
    if api not in APIS:
        raise ValueError(f"api of env {env_id!r} must be one of {', '.join(APIS)}, got {api!r}")
    for name, point in (("entry_point", entry_point), ("vector_entry_point", vector_entry_point)):
        if isinstance(point, str) and point.count(":") != 1:
            raise ValueError(f"{name} of env {env_id!r} must be 'module:attribute', got {point!r}")
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


def missing_dataset(env_id: str, **config) -> str | None:
    """Why ``env_id`` with ``config`` cannot be made here, its dataset being absent (``DatasetNotFound``), or None."""
    try:
        make_env(env_id, **config).close()
    except DatasetNotFound as error:
        return str(error)
    return None


def available_envs(api: str | None = None) -> list[EnvEntry]:
    """``registered_envs(api)`` but those that cannot be made here with their defaults (``missing_dataset``: a
    warning names each one left out)."""
    available = []
    for entry in registered_envs(api):
        if reason := missing_dataset(entry.id):
            warnings.warn(f"{entry.id} left out: {reason}", stacklevel=2)
        else:
            available.append(entry)
    return available


def env_entry(env_id: str) -> EnvEntry:
    """The entry of ``env_id``; ``ValueError`` naming it and listing the registered ids if it is unknown."""
    try:
        return _ENTRIES[env_id]
    except KeyError:
        raise ValueError(f"unknown env id {env_id!r}; choose from {', '.join(_ENTRIES)}") from None


def resolve_env_id(env_id: str) -> str:
    """``"module:id"`` (Gymnasium's prefix): import ``module`` (``ValueError`` if it fails) and return ``id``; an id
    without the prefix, or registered as it is, unchanged."""
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
    """Whether ``env_id`` is in this registry with a ``vector_entry_point`` (which takes ``SAME_STEP`` autoreset, its
    default, unlike Gymnasium's ``CartPoleVectorEnv``)."""
    try:
        entry = _ENTRIES.get(resolve_env_id(env_id))
    except ValueError:  # a module that does not import: make_env names it
        return False
    return entry is not None and entry.vector_entry_point is not None


def make_env(env_id: str, **config):
    """A new env: ``gym.make(env_id, **config)`` (also for ids only Gymnasium knows), or the PettingZoo parallel env.

    ``env_id`` may carry the module prefix (``resolve_env_id``). ``ValueError`` for an unknown id or a bad config.
    """
    env_id = resolve_env_id(env_id)
    if api_of(env_id) == PARALLEL:
        return _ENTRIES[env_id].load()(**config)
    try:
        return gym.make(env_id, **config)
    except gym.error.Error as error:
        raise ValueError(f"unknown env id {env_id!r} ({error}); choose from {', '.join(_ENTRIES)}") from None


def make_vector_env(env_id: str, num_envs: int, **config):
    """The native vector env of ``env_id`` (module prefix allowed) with ``num_envs`` copies, as ``gym.make_vec``;
    ``ValueError`` for an unknown id, no native vector env, or a bad config."""
    return env_entry(resolve_env_id(env_id)).load_vector()(num_envs=num_envs, **config)
