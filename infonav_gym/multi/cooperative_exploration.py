"""``CooperativeExplorationEnv``: a team maps a field, each robot choosing where to go and what to see (PettingZoo).

The PettingZoo view of one copy of ``CooperativeExplorationVectorEnv``, where the env is written once.
"""

from __future__ import annotations

from infonav_gym.multi.cooperative_exploration_vector import CooperativeExplorationVectorEnv
from infonav_gym.multi.exploration_planning import N_MOTIONS, NOOP_ACTION
from infonav_gym.multi.parallel_view import ParallelEnvView

__all__ = ["N_MOTIONS", "NOOP_ACTION", "CooperativeExplorationEnv"]


class CooperativeExplorationEnv(ParallelEnvView, vector_env=CooperativeExplorationVectorEnv):
    """A heterogeneous team maps a field; each robot chooses where to drive and what to observe, together.

    ## Description
    The paper's Section III-C, distributed heterogeneous multirobot exploration. The team
    starts at a base in one corner of a square Pymunk field (``exploration_field``) with
    round obstacles, GPS-denied canopy zones and a few landmarks, and must map the terrain:
    a grid of cells whose heights are Gaussian estimates (``terrain_map``). A robot that
    drives scans the cells around it; a position error ``sigma`` puts heights at the wrong
    place, so a scan's height noise grows as ``scan_std_m^2 + (terrain_slope * sigma)^2``:
    a badly localized robot maps poorly. A ``JointEKF`` over all poses fuses odometry, DGPS
    fixes (robots with DGPS, outside the canopies) and the observations the agents choose:
    a known landmark (range-bearing) or a teammate (relative pose, which correlates the two).

    Why a myopic agent fails: the robots without DGPS drift on odometry alone and stay
    localized only while a landmark or a well-localized teammate is within their sensor's
    short range. The unmapped cells lie far from both, so the action with the most immediate
    information (drive to fresh cells, observe whatever is in sight) leads the GPS-less
    robots away from every reference; their position std then crosses
    ``max_position_std_m`` and the team fails. Succeeding needs plans over several steps:
    scouts that cover far cells while returning near a teammate or a landmark in time, DGPS
    robots that escort them and leave the canopies, and a budget kept for when it matters.

    ## Agents
    ``robot_0 .. robot_{N-1}`` (default 4). Suites from ``robot_sensors`` (default: suite
    ``k % 4`` of ``gps+laser, gps+laser, laser, vision``; odometry always), speeds from
    ``robot_speeds_mps`` (default ``0.8, 0.8, 1.2, 1.2`` m/s: the DGPS robots are slower).
    The laser sees all around up to ``laser_range_m``, the camera a 60 deg field of view up
    to ``vision_range_m``; a robot observes landmarks and teammates with its one sensor.

    ## Action Space
    ``Discrete(5 * (1 + L + N))`` per agent, ``L = n_landmarks``: action ``a`` is slot
    ``a // 5`` and motion ``a % 5``. Slots: 0 observe nothing, ``1 + j`` landmark ``j``,
    ``1 + L + j`` ``robot_j``. A motion (``stay``, ``east``, ``north``, ``west``, ``south``)
    turns the robot on the spot for ``turn_time_s`` until its heading *estimated at the decision* is the
    compass heading, then drives it straight at its speed for the rest of the step (``stay`` does neither);
    Pymunk executes both phases, and both are exact unicycle motions for the EKF. A motion is valid while its
    true path keeps ``clearance.CLEARANCE_M`` (5 cm) from walls, obstacles and wherever a teammate's motions can take it
    (``world.clearance``): no contact ever pushes a robot unseen by its odometry. An observation is valid while the
    target is in range and field of view with a clear line of sight and the robot has budget
    left (``max_observations``); every observation goes with every valid motion, and action 0 (stay,
    observe nothing) is always valid. A masked
    action is action 0 (``invalid_action="noop"``) or raises ``ValueError`` (``"raise"``).

    ## Observation Space
    ``Box(float32, (10 + 5 N + 4 L + 3 + G,))``, ``G = map_cells_per_side^2``: the 10 own and
    5 per-robot features of ``cooperative_localization_v0``; per landmark: whether observing
    it is valid, its estimated range [m], ``cos, sin`` of its estimated bearing; the robot's
    speed [m/s], its budget left (fraction), the team's coverage; per cell (row-major from the
    lower left corner) the height std left, as a fraction of ``map_prior_std_m``. With
    ``observe_gains=True`` (off by default), ``5 (1 + L + N)`` more: ``action_information_gain`` of each
    action, the immediate expected gains the greedy agent ranks and the planner starts its search from.

    ## Rewards
    ``(1 - team_reward) * own_pose_information + team_reward * team_map_information`` plus
    the costs, with ``info["reward_terms"]``: ``own_pose_information``, the realized MI of
    the step's observations on the robot's own pose [nats]; ``team_map_information``, the map
    entropy reduction of every robot's scans this step [nats]; ``sensing_cost``
    ``-observation_cost_nats`` per observation; ``motion_cost`` ``-motion_cost_per_step`` per
    step driven; ``lost_penalty`` ``-lost_penalty`` for every robot when one is lost.
    ``info["action_information_gain"][a]`` is the immediate expected information of ``a``:
    ``(1 - team_reward)`` times the MI its observation alone brings to the robot's pose at the
    prior, plus ``team_reward`` times the map information its scan alone would bring, from the
    position the motion predicts, at the robot's current position std (0 where masked).
    A scan is taken only after driving forward: standing or turning in place sees the same
    view again, with the same errors, so it brings nothing new (action 0 has gain 0).

    ## Info
    ``infos[agent]``: ``action_mask`` (int8), ``action_information_gain``, ``reward_terms``,
    ``chosen_action``, ``invalid_action``, ``gps_available``, ``pose_std``, ``position_std_m``
    (largest, at the decision), ``pose_entropy``, ``position_error_m``, ``heading_error_rad``,
    ``true_pose``, ``estimated_pose``, ``time_s``, ``observations_left``, ``coverage``
    (team), ``lost`` (this robot), ``failed`` and ``success`` (the team).

    ## Starting State
    Parked at the base, facing the field's centre; estimates drawn from
    ``N(true pose, diag(initial_position_std_m^2, ..., initial_heading_std_rad^2))``; the map
    at its prior (std ``map_prior_std_m`` in every cell).

    ## Episode End
    Terminated for all agents when a robot's largest position std exceeds
    ``max_position_std_m`` (it is lost: ``failed``), or when the coverage reaches
    ``coverage_target`` (``success``); truncated after ``max_cycles`` steps (no success).

    ## Planning model
    ``planning_model()`` returns the model look-ahead agents search (``ExplorationPlanningModel`` of the
    env's one copy, ``multi.exploration_planning``): ``belief()`` copies the joint EKF state, the map and the
    budgets, ``plan_decision(belief, robot)`` and ``plan_step(belief, team_actions)`` step copies of it under
    the expected measurements with the env's own batched functions, never reading the true state
    (``agents.planner.PlannerAgent(env, robot)``).

    ## Arguments
    ``parallel_env(render_mode=None, **config)`` with any key of ``default_config()``; an
    unknown key or a bad value raises ``ValueError`` naming it. The env is the N = 1 view of
    ``CooperativeExplorationVectorEnv`` (its one implementation, ``self.vector``: ``scenario(0)``,
    ``true_poses``, ``joint_state()``, ``map_variances``, ``copy_state(0)``).

    ## Version History
    * v0: initial version (issue 18). Motions masked clear of contacts, and the planning model, added before
      any results were committed; the N = 1 view of the vector env since the one-implementation refactor
      (same numbers).
    """
