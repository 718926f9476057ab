"""Decentralized planning in a team env: each robot's ``PlannerAgent`` searches its own actions on the team model
while its teammates follow the plans they published at the last step (``TeamPlans``)."""

from __future__ import annotations

import weakref

import numpy as np

_BOARDS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()  # env -> its team's TeamPlans


class TeamPlans:
    """The plans a team's robots published: per robot, its latest two ``(decision step, actions)``."""

    def __init__(self, n_robots: int):
        self._plans = [[] for _ in range(n_robots)]

    @classmethod
    def of(cls, env) -> TeamPlans:
        """The board of ``env``'s team (one per env object: every robot's planner in it shares it)."""
        return _BOARDS.setdefault(env, cls(len(env.possible_agents)))

    def clear(self, robot: int) -> None:
        """Forget robot ``robot``'s plans (a new episode)."""
        self._plans[robot] = []

    def publish(self, robot: int, step: int, actions) -> None:
        """Robot ``robot``'s plan made at decision ``step``: its actions from that step on."""
        self._plans[robot] = [*self._plans[robot][-1:], (int(step), np.asarray(actions, dtype=int))]

    def actions_at(self, step: int, depths: np.ndarray, noop_action: int) -> np.ndarray:
        """Every robot's planned action ``depths`` (B,) steps after decision ``step`` (B, R), from the latest plan
        made before ``step``; ``noop_action`` beyond a plan or without one."""
        actions = np.full((len(depths), len(self._plans)), noop_action)
        for robot, plans in enumerate(self._plans):
            earlier = [(made, plan) for made, plan in plans if made < step]
            if earlier:
                made, plan = earlier[-1]
                index = step - made + np.asarray(depths)
                inside = index < len(plan)
                actions[inside, robot] = plan[index[inside]]
        return actions


class RobotPlanningView:
    """Robot ``robot``'s one-robot view of a team planning model, its teammates following ``plans``."""

    def __init__(self, model, robot: int, plans: TeamPlans, noop_action: int):
        self.model, self.robot, self.plans, self.noop_action = model, int(robot), plans, int(noop_action)
        self.n_primitives = model.n_primitives
        self.max_position_std_m = model.max_position_std_m
        self.idle_primitive = model.idle_primitive

    def belief(self):
        """The team's belief at the current decision (the model's)."""
        return self.model.belief()

    def plan_decision(self, belief):
        """The robot's ``(action_mask, action_information_gain)`` (B, A) at each belief."""
        return self.model.plan_decision(belief, self.robot)

    def plan_step(self, belief, actions):
        """One team step: the robot's ``actions`` (B,), its teammates' planned ones; its rewards (B,)."""
        team = self.plans.actions_at(self.model.step_index, belief.steps, self.noop_action)
        team[:, self.robot] = actions
        following, rewards = self.model.plan_step(belief, team)
        return following, rewards[:, self.robot]

    def position_std(self, covariances) -> np.ndarray:
        """The robot's largest position standard deviation at each belief (B,) [m]."""
        return self.model.position_std(covariances)[:, self.robot]

    def publish(self, actions) -> None:
        """Publish the robot's plan (its actions from the current decision on) for its teammates."""
        self.plans.publish(self.robot, self.model.step_index, actions)

    def clear(self) -> None:
        """Forget the robot's published plans (a new episode)."""
        self.plans.clear(self.robot)
