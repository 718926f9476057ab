"""The experiment harness: evaluation, training glue, benchmark and timing, paper figures, real-data replay, CLI.
It may import the core and ``agents``; nothing in the core imports it."""
