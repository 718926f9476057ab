"""``Driver``: the one driver of every env, a Gymnasium ``VectorEnv`` of N copies of one ``EnvScenario``.

It owns what no env writes again: the config merge and the shared keys, seeds per copy, reset, step, the three
autoreset modes, action checks (masked actions per ``invalid_action``), steps against the horizon, infos with
``_key`` masks, ``action_masks()`` and rendering of copy 0. An env's vector class is the driver bound to its scenario
(``class MyVectorEnv(Driver, scenario=MyScenario)``); its Gymnasium env is the driver at N = 1 with one agent
(``envs.single_view``), a team's PettingZoo env its N = 1 view (``envs.parallel_view``). A team scenario
(``EnvScenario.team``) takes actions (N, R) and gives rewards, terminations and truncations per robot (N, R).
"""

from __future__ import annotations

import os

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from infonav_gym.compiled import CopyThreads, kernel
from infonav_gym.config import check_choice, check_config, merge_config
from infonav_gym.envs.base import EPISODE_STEPS, INVALID_ACTION_MODES, RENDER_SIZE_PX, accepts_action
from infonav_gym.envs.protocol import EnvScenario
from infonav_gym.envs.vector_infos import autoreset_mode_of, final_step_infos, in_every_copy, set_rows
from infonav_gym.memory import check_memory

MASK_KEY = 'info["action_mask"]'


def is_seed(value) -> bool:
    """Whether ``value`` is a seed of one sub-env: None, or an int >= 0 (not a bool)."""
    return value is None or (isinstance(value, (int, np.integer)) and not isinstance(value, bool) and value >= 0)


def sub_env_seeds(seed, num_envs: int, owner: str) -> list[int | None]:
    """One seed per sub-env: ``s`` gives sub-env ``i`` the seed ``s + i``; a list gives one seed (or None) each.

    Raises:
        ValueError: naming ``owner``, for a seed that is not None, an int >= 0 or a list of ``num_envs`` of them.
    """
    if is_seed(seed):
        return [None if seed is None else int(seed) + copy for copy in range(num_envs)]
    seeds = list(seed) if isinstance(seed, (list, tuple)) else []
    if len(seeds) != num_envs or not all(is_seed(item) for item in seeds):
        raise ValueError(
            f"seed of {owner}.reset must be None, an int >= 0 or a list of {num_envs} such seeds (one per sub-env), "
            f"got {seed!r}"
        )
    return [None if item is None else int(item) for item in seeds]


class Driver(VectorEnv):
    """N copies of ``scenario_class``, each with its own generator: sub-env ``i`` after ``reset(seed=s)`` is the
    single env after ``reset(seed=s + i)``.

    ``autoreset_mode`` is one of ``AUTORESET_MODES`` per instance (``metadata["autoreset_mode"]``): ``SAME_STEP``,
    the default (the step that ends an episode returns the reset observation, the last one in ``info["final_obs"]`` /
    ``info["final_info"]``: SB3's and TorchRL's convention; TorchRL refuses ``NEXT_STEP``), ``NEXT_STEP`` (the step
    after a copy ended resets it, its action ignored, reward 0 and its reset info: Gymnasium's own vector envs' and
    RLlib's) or ``DISABLED`` (a copy goes on from its last state until ``reset()``). With a
    ``render_mode``, ``render()`` draws copy 0. ``state`` and ``decision`` are every copy's, now.
    """

    scenario_class: type[EnvScenario]
    AUTORESET_MODES = (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP, AutoresetMode.DISABLED)
    _renderer = None  # made by the first ``render()``
    _owner: str | None = None  # the single env's name, in the errors of its copy (``one_copy``)

    def __init_subclass__(cls, scenario: type[EnvScenario] | None = None, **kwargs):
        super().__init_subclass__(**kwargs)
        if scenario is not None:
            cls.scenario_class = scenario
            cls.metadata = {**scenario.metadata, "autoreset_mode": AutoresetMode.SAME_STEP}
            cls.episode_metrics, cls.traits = scenario.episode_metrics, scenario.traits
            cls.team_info_keys = scenario.team_info_keys

    @classmethod
    def default_config(cls) -> dict:
        """A fresh dict of every config key with its default; the constructor's keywords override it."""
        return cls.scenario_class.default_config()

    def __init__(
        self,
        num_envs: int = 1,
        render_mode: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.SAME_STEP,
        num_threads: int = 1,
        **config,
    ):
        """Check the arguments, the config and the memory the copies need, then build the scenario and its state;
        its kernels over the copies run on ``num_threads`` threads (the same numbers on any number).

        Raises:
            ValueError: for ``num_envs`` that is not an int >= 1, a render mode outside ``metadata``, an autoreset
                mode other than ``AUTORESET_MODES``, ``num_threads`` not from 1 to the CPU count, an unknown config
                key, a bad value, or copies that do not fit in the available memory.
        """
        owner = self.owner_name
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be None or one of {self.metadata['render_modes']}, got {render_mode!r}")
        self.config = merge_config(self.default_config(), config, owner)
        check_choice(self.config, "invalid_action", INVALID_ACTION_MODES, owner)
        shared = {"render_size_px": RENDER_SIZE_PX, "horizon": EPISODE_STEPS, "max_cycles": EPISODE_STEPS}
        check_config(self.config, owner, {key: interval for key, interval in shared.items() if key in self.config})
        if type(num_envs) is not int or num_envs < 1:
            raise ValueError(f"num_envs of {owner} must be an int >= 1, got {num_envs!r}")
        cpus = os.cpu_count() or 1
        if type(num_threads) is not int or not 1 <= num_threads <= cpus:
            raise ValueError(f"num_threads of {owner} must be an int from 1 to {cpus} (the CPUs), got {num_threads!r}")
        kb = self.copy_kb()
        check_memory(num_envs * kb * 1024, f"num_envs={num_envs} of {owner} (about {kb:.4g} kB a copy)")
        self.autoreset_mode = autoreset_mode_of(autoreset_mode, self.AUTORESET_MODES, owner)
        self.metadata = {**type(self).metadata, "autoreset_mode": self.autoreset_mode}
        self.num_envs, self.render_mode = num_envs, render_mode
        self.env_scenario = scenario = self.scenario_class(self.config, num_envs, owner, render_mode)
        scenario.threads = CopyThreads(num_threads)
        self.agents = list(scenario.agents)
        self._action_shape = (num_envs, len(self.agents)) if scenario.team else (num_envs,)
        self.single_observation_space, self.single_action_space = scenario.observation_space, scenario.action_space
        if scenario.team:
            low, high = scenario.observation_space.low, scenario.observation_space.high
            shape = (num_envs, len(self.agents), *low.shape)
            box = spaces.Box(np.broadcast_to(low, shape), np.broadcast_to(high, shape), dtype=np.float32)
            self.observation_space = box
            self.action_space = spaces.MultiDiscrete(np.full((num_envs, len(self.agents)), scenario.action_space.n))
        else:
            self.observation_space = batch_space(scenario.observation_space, num_envs)
            self.action_space = batch_space(scenario.action_space, num_envs)
        self._np_randoms: list[np.random.Generator | None] = [None] * num_envs
        self._everyone = np.arange(num_envs)
        self._prev_done = np.zeros(num_envs, dtype=bool)
        self._restarting = False  # whether any copy starts again in the next step (``_prev_done.any()``)
        self.state, self.decision = scenario.allocate(num_envs), None

    def copy_kb(self) -> float:
        """The memory a copy takes at this config [kB] (the scenario's ``copy_kb``)."""
        return self.scenario_class.copy_kb(self.config)

    @classmethod
    def one_copy(cls, owner: str, render_mode: str | None, config: dict) -> Driver:
        """One copy that never restarts by itself, its errors naming ``owner``: what the N = 1 views step."""
        env = cls.__new__(cls)
        env._owner = owner
        env.__init__(num_envs=1, render_mode=render_mode, autoreset_mode=AutoresetMode.DISABLED, **config)
        return env

    @property
    def horizon(self) -> int:
        """Every copy's episode length [steps]: the config's ``horizon`` (a team's ``max_cycles``); settable."""
        return self.config[self.env_scenario.horizon_key]

    @horizon.setter
    def horizon(self, steps: int) -> None:
        self.config[self.env_scenario.horizon_key] = steps

    @property
    def owner_name(self) -> str:
        """The env named in errors: the class, or the single env of a copy made by ``one_copy``."""
        return self._owner or type(self).__name__

    @property
    def np_randoms(self) -> list[np.random.Generator | None]:
        """Each sub-env's generator (the single env's ``np_random``), None before its first reset."""
        return list(self._np_randoms)

    def use_generator(self, copy: int, generator: np.random.Generator) -> None:
        """Sub-env ``copy`` draws its next episodes from ``generator`` (``reset()`` without a seed keeps it)."""
        self._np_randoms[copy] = generator

    # ------------------------------------------------------------------ reset and step

    def reset(self, *, seed: int | list | None = None, options: dict | None = None):
        """Reset every sub-env: seed ``s`` gives sub-env ``i`` the seed ``s + i``; a list gives one seed (or None) each.

        Raises:
            ValueError: for a seed that is not None, an int >= 0 or a list of N ints / None, or any options.
        """
        owner = self.owner_name
        if options:
            raise ValueError(f"{owner}.reset takes no options, got {sorted(options)}")
        for copy, copy_seed in enumerate(sub_env_seeds(seed, self.num_envs, owner)):
            if copy_seed is not None or self._np_randoms[copy] is None:
                self._np_randoms[copy] = seeding.np_random(copy_seed)[0]
        self._start(self._everyone)
        self._prev_done[:], self._restarting = False, False
        self.decision = self.env_scenario.decision(self.state, slice(None))
        return self._rendered(self._outputs(slice(None), np.zeros(self.num_envs, dtype=bool)))

    def step(self, actions):
        """Act in every sub-env, with ``autoreset_mode``'s resets.

        Raises:
            RuntimeError: before the first ``reset``.
            ValueError: for actions that are not one integer of the action space per copy (and robot), or, with
                ``invalid_action="raise"``, a masked action of a copy that has a valid one (naming it).
        """
        scenario, decision = self.env_scenario, self.decision
        acting, chosen = self._begin_step(actions)
        # with NEXT_STEP: the copies starting again take no step
        resetting = np.flatnonzero(self._prev_done) if self._restarting else None
        state = self.state = scenario.transition(self.state, decision, chosen, acting)
        rewards, terminated = scenario.reward(decision, chosen, state), scenario.terminal(state)
        if resetting is not None:
            rewards = np.where(acting.reshape(-1, *(1,) * (rewards.ndim - 1)), rewards, 0.0)
            terminated = terminated & acting
        truncated, ended, n_ended = counted_steps(state.elapsed, acting, terminated, self.horizon)
        if self.autoreset_mode == AutoresetMode.NEXT_STEP:
            if resetting is not None:
                self._start(resetting)
            self._prev_done, self._restarting = ended, n_ended > 0
        self.decision = scenario.decision(state, slice(None))
        observation, info = self._outputs(slice(None), acting)
        if self.autoreset_mode == AutoresetMode.SAME_STEP and n_ended:
            copies = np.flatnonzero(ended)
            final_infos = final_step_infos(observation, info, ended)
            self._start(copies)
            self._merge_decision(copies, scenario.decision(self.state, copies))
            reset_observation, reset_info = self._outputs(copies, np.zeros(len(copies), dtype=bool))
            observation[copies] = reset_observation
            set_rows(info, copies, reset_info)
            info.update(final_infos)
        self._rendered(None)
        if scenario.team:
            n_robots = len(self.agents)
            terminated, truncated = (np.repeat(flags[:, None], n_robots, axis=1) for flags in (terminated, truncated))
        return observation, rewards, terminated, truncated, info

    def _start(self, copies: np.ndarray) -> None:
        """New episodes in ``copies`` (ascending), each from its own generator."""
        self.state.elapsed[copies] = 0
        self.state = self.env_scenario.initial(self.state, copies, [self._np_randoms[copy] for copy in copies.tolist()])

    def _outputs(self, rows, stepped: np.ndarray) -> tuple:
        """The observations and infos of the copies ``rows`` at their decisions (``stepped``: which took a step), each
        info key with its ``_key`` mask (all hold)."""
        decision = self.decision
        if not isinstance(rows, slice):
            decision = type(decision)(*(field[rows] for field in decision))
        scenario, state = self.env_scenario, self.state
        info = scenario.info(state, decision, rows, stepped)
        if self._owner is None:  # a view of one copy reads row 0 and needs no masks
            info = in_every_copy(info, len(stepped))
        return scenario.observation(state, decision, rows), info

    def _merge_decision(self, copies: np.ndarray, decision) -> None:
        """Keep ``decision`` (a named tuple of arrays (n, ...)) as the decision of ``copies``, the others' kept."""
        rows = (set_rows(full, copies, part) for full, part in zip(self.decision, decision))
        self.decision = type(decision)(*rows)

    def _begin_step(self, actions) -> tuple[np.ndarray, np.ndarray]:
        """``(acting (N,), chosen (N, R))``: which copies act (with ``NEXT_STEP``, not those starting again) and each
        robot's action, -1 (the no-op) for a masked one (per ``invalid_action``) or in a copy not acting; raises as
        ``step`` (naming the copy and robot of a masked action)."""
        if self.decision is None:
            raise RuntimeError(f"{self.owner_name}: call reset() before step()")
        array, n_robots = np.asarray(actions), len(self.agents)
        if array.shape != self._action_shape or array.dtype.kind not in "iu":
            per = "one per copy and robot" if self.env_scenario.team else "one per sub-env"
            raise ValueError(
                f"actions of {self.owner_name} must be an integer array of shape {self._action_shape}, {per}, in "
                f"[0, {self.single_action_space.n - 1}]; got {array.dtype} of shape {array.shape}"
            )
        flat_actions = array.astype(np.int64, copy=False).reshape(-1)
        mask = self.decision.action_mask
        flat_mask = mask if mask.ndim == 2 else mask.reshape(-1, mask.shape[-1])
        accepted, outside, refused = accepted_actions(flat_actions, flat_mask, self._prev_done, n_robots)
        if outside >= 0:
            copy, robot = divmod(outside, n_robots)
            raise outside_action_space(flat_actions[outside], self._where(copy, robot), self.single_action_space)
        acting = ~self._prev_done
        if refused and self.config["invalid_action"] == "raise":  # with "noop" a masked action is the no-op
            for slot in np.flatnonzero(np.repeat(acting, n_robots) & (accepted < 0)).tolist():
                where = self._where(*divmod(slot, n_robots))
                accepts_action(int(flat_actions[slot]), flat_mask[slot], "raise", MASK_KEY, where)
        return acting, accepted.reshape(self.num_envs, n_robots)

    def _where(self, copy: int, robot: int) -> str | None:
        """The copy and robot an action error names (a single env's view names neither)."""
        if self.env_scenario.team:
            return f"{self.agents[robot]} in sub-env {copy}"
        return None if self._owner else f"sub-env {copy}"

    def action_masks(self) -> np.ndarray:
        """The valid actions of each copy (and robot) as bool (N, [R,] A); all ``True`` where none is valid (each is
        the no-op)."""
        if self.decision is None:
            raise RuntimeError(f"{self.owner_name}: call reset() before action_masks()")
        mask = self.decision.action_mask.astype(bool)
        mask[~mask.any(axis=-1)] = True
        return mask

    # ------------------------------------------------------------------ rendering

    def _rendered(self, outputs):
        """``outputs`` of a reset or step, after drawing sub-env 0 in ``"human"`` mode."""
        if self.render_mode == "human":
            self.render()
        return outputs

    def render(self):
        """Sub-env 0's frame (an RGB array for ``"rgb_array"``), drawn from the scenario's ``frame``; None without a
        mode."""
        owner = self.owner_name
        if self.render_mode is None:
            gym.logger.warn(f'{owner}.render() called without a render_mode; use render_mode="rgb_array"')
            return None
        if self.decision is None:
            raise RuntimeError(f"{owner}: call reset() before render()")
        if self._renderer is None:
            from infonav_gym.rendering import Renderer  # pygame only when drawing

            self._renderer = Renderer(self.render_mode, self.config["render_size_px"], self.metadata["render_fps"])
        return self._renderer.draw(self.env_scenario.frame(self.state, self.decision))

    def close_extras(self, **kwargs) -> None:
        self.decision = None
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    def __getstate__(self):
        state = self.__dict__.copy()
        state.pop("_renderer", None)  # a pygame window or surface does not pickle; the copy draws anew
        return state


def outside_action_space(action, where: str | None, space) -> ValueError:
    """The error for ``action`` of ``where`` (a sub-env, an agent in one) outside the ``Discrete`` ``space``."""
    of = "" if where is None else f" of {where}"
    return ValueError(
        f"action {action}{of} is not in the action space {space}: expected an integer in [0, {space.n - 1}]"
    )


@kernel
def accepted_actions(actions, mask, done, n_robots):
    """Each robot's action (N R,) where its copy acts (not ``done`` (N,)) and its ``mask`` (N R, A) allows it, else -1
    (the no-op); the first robot whose action is outside ``[0, A)`` (-1 if none); how many acting robots chose a
    masked action inside it."""
    chosen, outside, refused = np.empty(len(actions), dtype=np.int64), -1, 0
    for slot in range(len(actions)):
        action = actions[slot]
        inside = 0 <= action < mask.shape[1]
        if not inside and outside < 0:
            outside = slot
        acts = not done[slot // n_robots]
        allowed = inside and mask[slot, action] != 0
        refused += acts and inside and not allowed
        chosen[slot] = action if acts and allowed else -1
    return chosen, outside, refused


@kernel
def counted_steps(elapsed, acting, terminated, horizon):
    """Count the step of each ``acting`` sub-env in ``elapsed`` (N,), in place; ``(truncated, ended, n_ended)``:
    (N,) bool, it acted, did not terminate and reached ``horizon`` [steps]; (N,) bool, it terminated or was
    truncated; how many ended."""
    truncated, ended = np.empty(len(elapsed), dtype=np.bool_), np.empty(len(elapsed), dtype=np.bool_)
    n_ended = 0
    for copy in range(len(elapsed)):
        elapsed[copy] += acting[copy]
        truncated[copy] = acting[copy] and not terminated[copy] and elapsed[copy] >= horizon
        ended[copy] = terminated[copy] or truncated[copy]
        n_ended += ended[copy]
    return truncated, ended, n_ended
