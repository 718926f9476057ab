"""What every native vector env shares: its autoreset mode argument, and infos as dicts of arrays.

Infos follow Gymnasium's vector layout: each key holds an array with a leading sub-env dimension and a
``_key`` bool mask of the sub-envs that have it. They are flat, each value an array of numbers, as TorchRL's info
readers need: each reward term has its own key (``reward_term_key``), as Gymnasium's MuJoCo envs name theirs.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from gymnasium.vector import AutoresetMode

REWARD_TERM_PREFIX = "reward_"


def reward_term_key(term: str) -> str:
    """The info key of the reward term ``term``: ``"reward_" + term`` (``"reward_mutual_information"``)."""
    return REWARD_TERM_PREFIX + term


REWARD_TERMS_KEY = "reward_terms"  # a single env's info: its reward terms as one dict (ARCHITECTURE's contract)


def reward_terms_of(info: dict) -> dict:
    """The reward terms in ``info``, ``{term: value}`` in their order: a single env's ``info["reward_terms"]``, or
    the flat keys ``reward_term_key`` names (a vector or team env's)."""
    if REWARD_TERMS_KEY in info:
        return info[REWARD_TERMS_KEY]
    start = len(REWARD_TERM_PREFIX)
    return {key[start:]: value for key, value in info.items() if key.startswith(REWARD_TERM_PREFIX)}


def grouped_reward_terms(info: dict) -> dict:
    """``info`` (one copy's) with its flat reward-term keys gathered into ``info["reward_terms"]``, as a single
    env's info has them (TorchRL reads a vector env's flat ones; a single env's dict it leaves alone)."""
    terms = reward_terms_of(info)
    rest = {key: value for key, value in info.items() if not key.startswith(REWARD_TERM_PREFIX)}
    return {**rest, REWARD_TERMS_KEY: terms}


class Decision(NamedTuple):
    """Every copy's action mask (int8 (N, A), 1 = valid) and expected information gain of each action (N, A) [nats],
    0 where masked."""

    action_mask: np.ndarray
    action_information_gain: np.ndarray


def autoreset_mode_of(value, allowed: tuple[AutoresetMode, ...], owner: str) -> AutoresetMode:
    """``value`` as an ``AutoresetMode``: the enum, its value (``"SameStep"``) or its name (``"same_step"``).

    Raises:
        ValueError: naming ``owner`` and the modes it allows, for anything else.
    """
    for mode in allowed:
        if value is mode or (isinstance(value, str) and value.lower() in (mode.value.lower(), mode.name.lower())):
            return mode
    names = ", ".join(f"{mode.name.lower()!r}" for mode in allowed)
    raise ValueError(f"autoreset_mode of {owner} must be one of {names} (or the AutoresetMode), got {value!r}")


def decision_info(decision, stepped: np.ndarray, chosen: np.ndarray, terms: tuple, values: np.ndarray) -> dict:
    """The info keys every single-agent env has first, of n copies: their ``decision``'s mask and gains, their reward
    ``terms`` (each at its ``reward_term_key``) with their ``values`` (T, n) (0 where a copy did not step,
    ``stepped`` (n,) bool: just reset, so that every info has the same keys, as recorders such as Minari's need), the
    action each took (``chosen`` (n,), -1: none or the no-op) and whether it was invalid."""
    if np.count_nonzero(stepped) == len(stepped):  # the usual step: ``np.where``'s numbers, at less cost
        values, chosen = values.copy(), chosen.copy()
    else:
        values, chosen = np.where(stepped, values, 0.0), np.where(stepped, chosen, -1)
    return {
        "action_mask": decision.action_mask.copy(),
        "action_information_gain": decision.action_information_gain.copy(),
        **{reward_term_key(term): value for term, value in zip(terms, values)},
        "chosen_action": chosen,
        "invalid_action": stepped & (chosen < 0),
    }


def in_every_copy(info: dict, n_copies: int) -> dict:
    """``info`` with a ``_key`` mask holding for all ``n_copies`` beside each of its keys."""
    everyone = np.ones(n_copies, dtype=bool)
    return {**info, **{"_" + key: everyone for key in info}}


def set_rows(full, rows: np.ndarray, part):
    """Write ``part``'s rows into ``full`` at ``rows`` (arrays, or a dict of them); returns ``full``."""
    if isinstance(full, dict):
        for key, value in full.items():
            set_rows(value, rows, part[key])
        return full
    full[rows] = part
    return full


def final_step_infos(observation: np.ndarray, info: dict, ended: np.ndarray) -> dict:
    """Gymnasium's ``SAME_STEP`` keys for the sub-envs ``ended`` (N,) bool: their last observation and info.

    ``final_obs`` is an object array of the ended sub-envs' observations (``None`` elsewhere); ``final_info`` a
    copy of ``info`` whose masks hold only for them; ``_final_obs`` and ``_final_info`` are ``ended``.
    """
    final_obs = np.full(len(ended), None, dtype=object)
    for row in np.flatnonzero(ended).tolist():
        final_obs[row] = observation[row].copy()
    return {
        "final_obs": final_obs,
        "_final_obs": ended.copy(),
        "final_info": _masked_copy(info, ended),
        "_final_info": ended.copy(),
    }


def _masked_copy(info: dict, rows: np.ndarray) -> dict:
    return {key: value & rows if key.startswith("_") else value.copy() for key, value in info.items()}
