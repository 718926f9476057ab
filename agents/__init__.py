"""Baseline agents for the infonav environments."""

from agents.base import Agent, valid_actions
from agents.everything import EverythingAgent
from agents.greedy_entropy import GreedyEntropyAgent
from agents.nearest import NearestAgent
from agents.planner import PlannerAgent
from agents.random_agent import RandomAgent

__all__ = [
    "Agent",
    "EverythingAgent",
    "GreedyEntropyAgent",
    "NearestAgent",
    "PlannerAgent",
    "RandomAgent",
    "valid_actions",
]
