"""Issue 16's registration criterion on ``results/registration_recall.json`` (five sets of 50 terrain pairs).

The committed tables are made by ``python scripts/registration_recall.py`` (about 8 minutes); the
suite re-registers the first pair of each set and checks it against them, then judges the tables:
the default registration by recall, and the "entropy" control points by recall and median.
"""

import json
from pathlib import Path

import numpy as np
import pytest

from infonav_gym.experiments.registration_recall import best_candidate, candidate_table
from infonav_gym.experiments.reproduce.fig6 import seed_statistics
from infonav_gym.registration.frame_pairs import FRAME_PAIR_ICP

RESULT = Path(__file__).resolve().parents[1] / "results" / "registration_recall.json"
RECALL_POINTS = 0.03  # "within 3 points" of recall, as a fraction
MEDIAN_RATIO = 1.2  # "within 20%" of the all-points median
TRIED = (
    "tried on sets 0-49 and 200-249 (entropy / all medians, 1.35 and 1.95 as committed): a per-patch bias term "
    "(errors a_i + b^2 shared in a patch, b = 1 cm: 1.38, 1.96; 2 cm: 1.34, 1.88), footprint bias 0 (1.51, 2.50) "
    "and 1 (1.27, 2.20), patches of 4 x 5 (1.60, 1.90) and 16 x 20 pixels (1.91, 2.33); none kept"
)


@pytest.fixture(scope="module")
def committed() -> dict:
    return json.loads(RESULT.read_text())


@pytest.fixture(scope="module")
def control_points(committed) -> list[dict]:
    """Per seed set, strategy -> its summary with the default registration."""
    return committed["control_points"]


def test_the_committed_tables_reproduce_on_the_first_pair_of_each_set(committed):
    first_pairs = [range(first, first + 1) for first, _ in committed["seed_sets"]]
    for name, per_set in candidate_table(first_pairs[:1]).items():
        expected = committed["candidates"][name]["sets"][0]["errors_after_m"][0]
        assert per_set[0]["errors_after_m"][0] == pytest.approx(expected, rel=1e-6, abs=1e-9), name
    for index, seeds in enumerate(first_pairs):
        for name, summary in seed_statistics(seeds)["methods"].items():
            expected = committed["control_points"][index][name]["errors_after_m"][0]
            assert summary["errors_after_m"][0] == pytest.approx(expected, rel=1e-6, abs=1e-9), (index, name)


def test_frame_pairs_use_the_best_registration_by_recall(committed):
    table = {name: entry["sets"] for name, entry in committed["candidates"].items()}
    assert committed["candidates"][best_candidate(table)]["settings"] == FRAME_PAIR_ICP
    assert committed["frame_pair_icp"] == FRAME_PAIR_ICP


def test_all_points_recall_at_5_cm_is_at_least_95_percent_on_every_set(control_points):
    assert min(methods["all"]["recall_5cm"] for methods in control_points) >= 0.95


def test_entropy_uses_a_quarter_of_the_returns(control_points):
    for methods in control_points:
        assert methods["entropy"]["mean_points"] <= 0.25 * methods["all"]["mean_points"] + 0.5


def _measured(control_points) -> str:
    rows = []
    for methods in control_points:
        every, entropy, random = (methods[name] for name in ("all", "entropy", "random"))
        rows.append(
            f"recall {entropy['recall_5cm']:.2f} (all {every['recall_5cm']:.2f}, random {random['recall_5cm']:.2f}), "
            f"median {1e3 * entropy['median_error_after_m']:.1f} mm (all {1e3 * every['median_error_after_m']:.1f}, "
            f"random {1e3 * random['median_error_after_m']:.1f})"
        )
    return "; ".join(rows)


def _not_reached(measured: str):
    """A strict xfail (a tripwire: passing would mean the criterion now holds and the mark must go)."""
    return pytest.mark.xfail(reason=f"not reached: {measured}; {TRIED}", strict=True)


@_not_reached(
    "entropy 5 cm recall 0.96, 0.96, 0.92, 0.96, 1.00 against all points' 1.00, 0.98, 0.98, "
    "0.98, 1.00 (4 and 6 points short on sets 0-49 and 200-249, 10 cm recall 0.94 vs 1.00 there)"
)
def test_entropy_recall_is_within_3_points_of_all_points_on_every_set(control_points):
    for methods in control_points:
        for limit in ("recall_5cm", "recall_10cm"):
            assert methods["entropy"][limit] >= methods["all"][limit] - RECALL_POINTS - 1e-12, _measured(control_points)


@_not_reached(
    "entropy / all-points medians 1.35, 1.71, 2.02, 1.89, 1.49 (7.7-9.5 mm against 4.5-6.1 mm; "
    "random's 1.45-1.90); with GICP the quarter chosen from one frame does no better than random"
)
def test_entropy_median_is_within_20_percent_of_all_points_on_every_set(control_points):
    ratios = [m["entropy"]["median_error_after_m"] / m["all"]["median_error_after_m"] for m in control_points]
    assert max(ratios) <= MEDIAN_RATIO, f"entropy / all medians {np.round(ratios, 2).tolist()}"


@_not_reached(
    "entropy 5 cm recall below random's on sets 0-349 (0.96, 0.96, 0.92, 0.96 vs 1.00, 0.98, "
    "0.98, 0.98), median above random's on sets 200-449 (9.5, 8.6, 9.1 vs 7.6, 7.4, 8.8 mm)"
)
def test_entropy_recall_and_median_are_at_least_randoms_on_every_set(control_points):
    for methods in control_points:
        entropy, random = methods["entropy"], methods["random"]
        assert entropy["recall_5cm"] >= random["recall_5cm"], _measured(control_points)
        assert entropy["median_error_after_m"] <= random["median_error_after_m"], _measured(control_points)
