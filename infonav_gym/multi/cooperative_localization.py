"""``CooperativeLocalizationEnv``: a heterogeneous team localizes through relative-pose observations (PettingZoo).

The PettingZoo view of one copy of ``CooperativeLocalizationVectorEnv``, where the env is written once.
"""

from __future__ import annotations

from infonav_gym.multi.cooperative_localization_vector import CooperativeLocalizationVectorEnv
from infonav_gym.multi.parallel_view import ParallelEnvView
from infonav_gym.multi.team_localization import start_episode
from infonav_gym.multi.team_observations import team_observations
from infonav_gym.multi.team_sensing import NO_OBSERVATION, SensingPairs

__all__ = ["NO_OBSERVATION", "CooperativeLocalizationEnv", "SensingPairs", "start_episode", "team_observations"]


class CooperativeLocalizationEnv(ParallelEnvView, vector_env=CooperativeLocalizationVectorEnv):
    """Robots without (or losing) DGPS localize through relative-pose observations of teammates.

    ## Description
    The paper's Section III-C. N robots follow their routes in a Pymunk world; a
    joint EKF over all poses fuses every robot's odometry, the DGPS fixes of
    the robots that have them (DGPS drops out on a time schedule and under
    GPS-denied canopy zones) and the relative-pose observations the agents choose.
    Each step each robot may observe one teammate with its laser or camera: the
    measured range, bearing and relative heading update both robots' poses and
    correlate them. A greedy-entropy agent picks the teammate whose observation
    brings the most information on its own pose.

    ## Agents
    ``robot_0 .. robot_{N-1}`` (``team_field`` fits up to 4 robots in its default
    40 m field; ``convoy`` any number). Each robot's sensor suite comes from
    ``robot_sensors`` (default: suite ``k % 4`` of ``gps+laser, gps+laser,
    laser, vision``; odometry always).

    ## Action Space
    ``Discrete(N + 1)`` per agent: 0 = no relative observation (always valid),
    ``1 + j`` = observe ``robot_j``. Valid when the robot carries a relative-pose
    sensor, ``robot_j`` is another robot inside its range and field of view and no
    wall or obstacle blocks the line of sight (``infos[agent]["action_mask"]``). A
    masked action is a no-op (``invalid_action="noop"``, the default, as in the
    single-agent envs) or raises ``ValueError`` (``invalid_action="raise"``). An
    integer outside the space always raises ``ValueError``.

    ## Observation Space
    ``Box(float32, (10 + 5 N,))`` per agent: the robot's estimated ``x, y`` [m],
    ``cos, sin`` of its estimated heading, standard deviations of ``x, y`` [m] and
    heading [rad], its pose entropy [nats], whether it has a DGPS fix now, and the
    elapsed fraction of ``max_cycles``; then per robot ``j``: whether observing it
    is valid, its estimated range [m], ``cos, sin`` of its estimated bearing and its
    position standard deviation [m] (zeros for the robot itself). With
    ``observe_gains=True``, ``N + 1`` more: ``action_information_gain`` of each
    action (what a greedy agent ranks by [nats]), so ``Box(float32, (11 + 6 N,))``.

    ## Rewards
    The realized mutual information on the robot's own pose of this step's
    relative-pose updates, ``0.5 ln(det P_ii,prior / det P_ii,post)`` [nats], mixed
    with the team's (the MI on the joint state) by ``team_reward`` in [0, 1]:
    ``(1 - team_reward) * own + team_reward * team``. The observations of one step
    are taken at the same time and fused as one stacked EKF update, so a robot's
    reward also counts what teammates' observations of it brought;
    ``action_information_gain[a]`` is the MI action ``a`` alone would bring to the
    robot's own pose at the step's prior.

    ## Info
    ``infos[agent]``: ``action_mask`` (int8), ``action_information_gain`` (expected
    reward of each action [nats], 0 where masked), ``reward_terms`` (own and team MI),
    ``chosen_action``, ``invalid_action``, ``gps_available``, ``pose_std`` (x, y,
    heading std at the step's prior), ``pose_std_after_update`` (right after the
    step's relative updates), ``pose_entropy``, ``position_error_m``,
    ``heading_error_rad``, ``true_pose``, ``estimated_pose``, ``time_s``.

    ## Starting State
    The robots at their routes' starts; initial estimates drawn from
    ``N(true pose, diag(initial_position_std_m^2, ..., initial_heading_std_rad^2))``.

    ## Episode End
    All agents are truncated after ``max_cycles`` steps; never terminated.

    ## Arguments
    ``parallel_env(render_mode=None, **config)`` with any key of
    ``default_config()``; an unknown key raises ``ValueError`` naming it.
    The env is the N = 1 view of ``CooperativeLocalizationVectorEnv`` (its one
    implementation, ``self.vector``: ``scenario(0)``, ``true_poses``,
    ``joint_state()``); its EKF equals filterpy's ``JointEKF`` update for update.
    ``estimator="independent"`` drops the cross-covariances (overconfident, for
    comparison).

    ## Version History
    * v0: initial version; the N = 1 view of the vector env since the one-implementation refactor (same numbers).
    """
