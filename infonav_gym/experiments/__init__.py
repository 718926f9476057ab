"""The experiment harness: evaluation, training glue, benchmark and timing, paper figures, real-data replay, CLI.

It runs experiments on the core (envs, estimation, world, sensors, registration) and may
import ``agents``; nothing in the core imports it.
"""
