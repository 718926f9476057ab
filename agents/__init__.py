"""Baseline agents for the infonav environments."""

from agents.base import Agent, valid_actions
from agents.greedy_entropy import GreedyEntropyAgent
from agents.planner import PlannerAgent
from agents.random_agent import RandomAgent

__all__ = ["Agent", "GreedyEntropyAgent", "PlannerAgent", "RandomAgent", "valid_actions"]
