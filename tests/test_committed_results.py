"""Every committed evaluation in ``results/`` reproduces on its first seeds (``scripts/check_committed_results.py``):
decisions (integers, rates) exactly, floating-point figures to 1e-6 relative, which last-digit differences between
CPUs cannot exceed and one different decision does."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

# the committed evaluations replayed: slow; `pytest -m "not slow"` leaves it out while developing
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "check_committed_results.py"


def load_script():
    spec = importlib.util.spec_from_file_location("check_committed_results", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_decisions_compare_exactly_and_figures_to_a_tolerance():
    script = load_script()
    assert script.exact_metrics("cooperative_exploration_v0") == {"success_rate", "failure_rate"}
    assert not script.reproduced(86, 87, exact=False, rtol=1e-6), "an episode length is a decision"
    assert not script.reproduced(1.0, 1.0 + 1e-12, exact=True, rtol=1e-6), "so is a rate"
    assert script.reproduced(829.1473532054413, 829.1473532054413 * (1 + 1e-13), exact=False, rtol=1e-6)
    assert not script.reproduced(829.15, 860.32, exact=False, rtol=1e-6)
    assert not script.reproduced(0.5, None, exact=False, rtol=1e-6), "a metric missing from the fresh run"


def test_committed_evaluations_reproduce_on_their_first_two_seeds():
    completed = subprocess.run(
        [sys.executable, str(SCRIPT), "--episodes", "2"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert completed.returncode == 0, completed.stdout[-3000:] + completed.stderr[-3000:]
    assert completed.stdout.count(": reproduced") >= 11, completed.stdout
