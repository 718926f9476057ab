"""What an env promises about itself (``EnvTraits``), and how the harness reads an env's declarations: every env
class declares ``episode_metrics`` (``EpisodeMetric``, what ``infonav evaluate`` reports) and ``traits``."""

from __future__ import annotations

from dataclasses import dataclass

COMMON_INFO_KEYS = frozenset(
    {"action_mask", "action_information_gain", "chosen_action", "invalid_action", "true_pose", "time_s"}
)  # in every info of every single-agent infonav env, with its ``reward_terms``
POSE_INFO_KEYS = frozenset(
    {"pose_entropy", "state_entropy", "position_error_m", "heading_error_rad", "estimated_pose"}
)  # in every info of an env with ``estimates_pose``


@dataclass(frozen=True)
class EnvTraits:
    """The properties of an env that code outside it may rely on, instead of knowing its id.

    Attributes:
        estimates_pose: an EKF tracks the robot's pose; infos hold ``POSE_INFO_KEYS`` and the reward
            term ``"mutual_information"``, the realized MI of the pose update [nats].
        reports_success: the last info of an episode holds a bool ``info["success"]``.
        may_terminate: episodes may end before the horizon (``terminated``); otherwise only truncation.
        rewards_information_at_once: a valid action with a positive expected gain earns a positive
            reward in the same step.
        gain_known_before_measuring: (with ``estimates_pose``) an action's expected gain is the MI it then brings:
            the update's noise is known before measuring. False where it is known only after (a registration's
            covariance comes from its own matches): the gain is then a prediction.
        idle_actions: valid actions whose expected information gain is always 0 (wait, move without observing).
        valid_gain_may_be_zero: a valid action other than the idle ones may have gain 0 (e.g. a patch
            without usable points); otherwise its gain is positive.
        reward_terms: the reward's terms, in order, each in every info at its ``reward_term_key`` (``"reward_" +
            term``, flat as TorchRL's info readers need) (empty: not declared).
        info_keys: info keys the env adds to ``COMMON_INFO_KEYS`` (and ``POSE_INFO_KEYS``).
        reward_config_keys: config keys that decide what the reward means (e.g. ``team_reward``); every
            evaluation names their values in its heading, so a default reward choice is visible.
        noop_action: an action that observes nothing, which the random baseline takes only when nothing
            else is valid (``RandomAgent(noop_action=...)``); ``None``: the random baseline picks among all
            valid actions.
        everything_action: the action that observes all there is at once (register every return of a scan), which
            the ``everything`` reference agent takes; ``None``: the env has none.
        main_metric: the name of the ``episode_metrics`` entry that ranks agents on the env, higher being better
            (``infonav leaderboard`` reports it); every infonav env names one.
        reward_unit: the unit of a reward and a return, as plots write it in brackets (``"nats"``).
        kb_per_copy: the memory a copy of its vector env takes [kB] at the default config: within a factor 4 of
            both the benchmark's ``*_kb_per_env`` (peak RSS growth) and the allocations numpy and Python trace
            (``tests/test_sizes.py``); a vector env refuses more copies than the available memory holds, before
            allocating them (0: not declared, not checked).
    """

    estimates_pose: bool = False
    reports_success: bool = False
    may_terminate: bool = False
    rewards_information_at_once: bool = False
    gain_known_before_measuring: bool = True
    idle_actions: frozenset[int] = frozenset()
    valid_gain_may_be_zero: bool = False
    reward_terms: tuple[str, ...] = ()
    info_keys: frozenset[str] = frozenset()
    reward_config_keys: tuple[str, ...] = ()
    noop_action: int | None = None
    everything_action: int | None = None
    main_metric: str = ""
    reward_unit: str = "nats"
    kb_per_copy: float = 0.0


def has_planning_model(env_or_class) -> bool:
    """Whether the env (wrapped or not) or env class offers a planning model: a ``planning_model()`` method
    returning what ``agents.planner.PlannerAgent`` searches (``belief``, ``plan_decision``, ``plan_step``)."""
    owner = env_or_class if isinstance(env_or_class, type) else env_or_class.unwrapped
    return callable(getattr(owner, "planning_model", None))


def traits_of(env) -> EnvTraits:
    """The ``traits`` the env (wrapped or not) declares; ``EnvTraits()`` (no promises) if it declares none."""
    return getattr(env.unwrapped, "traits", EnvTraits())


def episode_metrics_of(env) -> tuple:
    """The ``episode_metrics`` the env (wrapped or not) declares.

    Raises:
        ValueError: if it declares none, naming its class.
    """
    metrics = getattr(env.unwrapped, "episode_metrics", None)
    if not metrics:
        raise ValueError(
            f"{type(env.unwrapped).__name__} declares no episode_metrics: give the class a tuple of "
            "infonav_gym.envs.metrics.EpisodeMetric to evaluate it"
        )
    return tuple(metrics)


def main_metric_of(env):
    """The ``EpisodeMetric`` the env's ``traits.main_metric`` names.

    Raises:
        ValueError: if it names none of the env's ``episode_metrics``, naming its class and the choices.
    """
    metrics, name = episode_metrics_of(env), traits_of(env).main_metric
    for metric in metrics:
        if metric.name == name:
            return metric
    raise ValueError(
        f"{type(env.unwrapped).__name__}.traits.main_metric is {name!r}, not one of its episode_metrics: "
        f"name one of {', '.join(metric.name for metric in metrics)}"
    )
