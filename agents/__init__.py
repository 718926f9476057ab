"""Baseline agents for the infonav environments."""

from agents.base import Agent, valid_actions
from agents.greedy_entropy import GreedyEntropyAgent
from agents.random_agent import RandomAgent

__all__ = ["Agent", "GreedyEntropyAgent", "RandomAgent", "valid_actions"]
