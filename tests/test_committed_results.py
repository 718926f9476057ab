"""Every committed evaluation in ``results/`` reproduces on its first seeds (``scripts/check_committed_results.py``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_committed_evaluations_reproduce_on_their_first_two_seeds():
    completed = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "check_committed_results.py"), "--episodes", "2"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert completed.returncode == 0, completed.stdout[-3000:] + completed.stderr[-3000:]
    assert completed.stdout.count(": reproduced") >= 11, completed.stdout
