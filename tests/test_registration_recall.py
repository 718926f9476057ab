"""Issues 26 and 44's control-point comparison on ``results/registration_recall.json`` (five sets of 50 terrain pairs).

The committed tables are made by ``python scripts/registration_recall.py`` (see ``results/README.md`` for how
long it takes); the suite re-registers the first pair of each set and checks the errors against them (the
times are the machine's), then judges the tables: the default registration by recall, the default selector by
recall, and issue 44's control-point criterion for the information-based selectors against the field's standard
selectors at 10 % and 25 % of the returns. The harness itself runs on one pair per set at small budgets.
"""

import importlib.util
import json
from pathlib import Path

import pytest

from infonav_gym.experiments.registration_recall import (
    BUDGETS,
    SELECTORS,
    best_candidate,
    budget_label,
    candidate_table,
    check_budgets,
    control_point_comparison,
    pair_runs,
)
from infonav_gym.registration.control_points import DEFAULT_CONTROL_POINT_STRATEGY
from infonav_gym.registration.frame_pairs import FRAME_PAIR_ICP

ROOT = Path(__file__).resolve().parents[1]
RESULT = ROOT / "results" / "registration_recall.json"
SCRIPT = ROOT / "scripts" / "registration_recall.py"
ACCEPTANCE_BUDGETS = (budget_label(0.10), budget_label(0.25))  # the criterion's budgets; the last one is judged by time
STANDARD_SELECTORS = ("random", "uniform", "normal_space", "covariance")
INFORMATION_SELECTORS = ("entropy", "stratified_information")
MEDIAN_FACTOR = 1.5  # at a quarter, the median error may be this many times all returns'
TIME_FACTOR = 0.5  # at a quarter, selection and ICP may take this fraction of all returns' ICP time


@pytest.fixture(scope="module")
def committed() -> dict:
    return json.loads(RESULT.read_text())


@pytest.fixture(scope="module")
def comparison(committed) -> dict:
    """The control-point comparison: all returns and, per budget, selector -> per seed set, its summary."""
    return committed["control_points"]


def load_script():
    spec = importlib.util.spec_from_file_location("registration_recall_script", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_committed_tables_reproduce_on_the_first_pair_of_each_set(committed, comparison):
    first_pairs = [range(first, first + 1) for first, _ in committed["seed_sets"]]
    for name, per_set in candidate_table(first_pairs[:1]).items():
        expected = committed["candidates"][name]["sets"][0]["errors_after_m"][0]
        assert per_set[0]["errors_after_m"][0] == pytest.approx(expected, rel=1e-6, abs=1e-9), name
    for index, (seed,) in enumerate(first_pairs):
        runs = pair_runs(seed, comparison["budgets"])
        expected = comparison["all"][index]["errors_after_m"][0]
        assert runs["all"]["error_after_m"] == pytest.approx(expected, rel=1e-6, abs=1e-9), (seed, "all")
        for label, selectors in comparison["by_budget"].items():
            for selector, per_set in selectors.items():
                expected = per_set[index]["errors_after_m"][0]
                assert runs[label][selector]["error_after_m"] == pytest.approx(expected, rel=1e-6, abs=1e-9), (
                    seed,
                    label,
                    selector,
                )


def test_frame_pairs_use_the_best_registration_by_recall(committed):
    table = {name: entry["sets"] for name, entry in committed["candidates"].items()}
    assert committed["candidates"][best_candidate(table)]["settings"] == FRAME_PAIR_ICP
    assert committed["frame_pair_icp"] == FRAME_PAIR_ICP


def test_all_points_recall_at_5_cm_is_at_least_95_percent_on_every_set(comparison):
    assert min(row["recall_5cm"] for row in comparison["all"]) >= 0.95


def test_every_selector_registers_50_pairs_per_set_with_the_same_points_its_budgets_fraction(comparison):
    assert comparison["budgets"] == list(BUDGETS) and comparison["selectors"] == list(SELECTORS)
    assert list(comparison["by_budget"]) == [budget_label(budget) for budget in BUDGETS]
    for budget, (label, selectors) in zip(BUDGETS, comparison["by_budget"].items()):
        for index, every in enumerate(comparison["all"]):
            points = {selectors[selector][index]["mean_points"] for selector in SELECTORS}
            assert len(points) == 1, (label, index, "every selector is given the same points")
            shortfall = budget * every["mean_points"] - points.pop()
            assert -0.5 <= shortfall <= 0.5 or comparison["capped_pairs"][label][index] > 0, (label, index)
            for selector in SELECTORS:
                row = selectors[selector][index]
                assert len(row["errors_after_m"]) == len(row["times_s"]) == 50 and row["mean_time_s"] > 0.0


def test_the_default_selector_is_the_best_measured_by_recall(comparison):
    """The registrations' rule (lowest 5 cm recall over the sets, then mean recall, then mean median) over the
    criterion's budgets."""
    table = {
        selector: [row for label in ACCEPTANCE_BUDGETS for row in comparison["by_budget"][label][selector]]
        for selector in SELECTORS
    }
    assert best_candidate(table) == DEFAULT_CONTROL_POINT_STRATEGY


def _shortfalls(comparison, selector: str) -> list[str]:
    """Where ``selector`` misses issue 44's criterion, one line each: at ``ACCEPTANCE_BUDGETS`` on every set, 5 cm
    recall >= and median <= each standard selector's; at a quarter, median <= ``MEDIAN_FACTOR`` x all returns' and
    mean time (selection + ICP) <= ``TIME_FACTOR`` x all returns'."""
    misses, every = [], comparison["all"]
    for label in ACCEPTANCE_BUDGETS:
        selectors = comparison["by_budget"][label]
        for index, row in enumerate(selectors[selector]):
            for name in STANDARD_SELECTORS:
                other = selectors[name][index]
                if row["recall_5cm"] < other["recall_5cm"]:
                    misses.append(
                        f"{label} set {index} recall {row['recall_5cm']:.2f} < {name}'s {other['recall_5cm']:.2f}"
                    )
                if row["median_error_after_m"] > other["median_error_after_m"]:
                    misses.append(
                        f"{label} set {index} median {1e3 * row['median_error_after_m']:.2f} mm > {name}'s "
                        f"{1e3 * other['median_error_after_m']:.2f} mm"
                    )
    for index, row in enumerate(comparison["by_budget"][ACCEPTANCE_BUDGETS[-1]][selector]):
        if row["median_error_after_m"] > MEDIAN_FACTOR * every[index]["median_error_after_m"]:
            misses.append(
                f"25% set {index} median {1e3 * row['median_error_after_m']:.2f} mm > {MEDIAN_FACTOR} x all's "
                f"{1e3 * every[index]['median_error_after_m']:.2f} mm"
            )
        if row["mean_time_s"] > TIME_FACTOR * every[index]["mean_time_s"]:
            misses.append(
                f"25% set {index} time {1e3 * row['mean_time_s']:.1f} ms > {TIME_FACTOR} x all's "
                f"{1e3 * every[index]['mean_time_s']:.1f} ms"
            )
    return misses


@pytest.mark.xfail(
    reason="not reached (a strict xfail: passing would mean the criterion now holds and the mark must go): "
    "stratified_information, the better information-based selector, misses 31 of the 90 checks: its 5 cm recall is "
    "below random's at 10 % on sets 0-349 (98, 96, 94, 94 % against 100, 98, 96, 96 %) and at 25 % on sets 0-49 "
    "and 300-349 (96, 98 % against 98, 100 %); its 25 % median is the lowest of all selectors on sets 100-149 and "
    "400-449 (6.45, 7.59 mm) but above 1.5 x all returns' on sets 200-349 (8.27, 7.89 mm against 7.07, 6.81 mm); "
    "its selection and ICP at 25 % take 12.5-14.9 ms, above half of all returns' ICP (11.4-14.0 ms) on every set. "
    "entropy misses 59 (tuned on seeds 1000-1049; results/README.md)",
    strict=True,
)
def test_an_information_based_selector_meets_the_control_point_criterion_on_every_set(comparison):
    misses = {selector: _shortfalls(comparison, selector) for selector in INFORMATION_SELECTORS}
    assert any(not found for found in misses.values()), misses


def test_the_script_writes_a_table_per_budget_and_the_plot(tmp_path, monkeypatch):
    script = load_script()
    monkeypatch.setattr(script, "SEED_SETS", (range(0, 1), range(100, 101)))
    output = tmp_path / "recall"
    assert script.main(["--pairs", "1", "--budgets", "0.02,0.05", "--output", str(output)]) == 0
    assert output.with_suffix(".png").stat().st_size > 10_000
    written = json.loads(output.with_suffix(".json").read_text())
    assert list(written["control_points"]["by_budget"]) == ["2%", "5%"]
    lines = output.with_suffix(".md").read_text().splitlines()
    for label in ("2%", "5%"):
        start = lines.index(f"### {label} of the returns")
        header, rule, *rows = lines[start + 2 : start + 5 + len(SELECTORS)]
        assert header == "| control points | 0-0 | 100-100 |" and rule == "| --- | ---: | ---: |"
        assert [row.split(" | ")[0] for row in rows] == [f"| {name}" for name in ("all", *SELECTORS)]
        assert all(row.count(" ms |") == 2 for row in rows)


@pytest.mark.parametrize("budgets", [(0.0,), (1.5,), (-0.25,), (0.25, 0.25), (), (True,), ("0.25",)])
def test_a_budget_outside_0_1_or_repeated_is_a_value_error(budgets):
    with pytest.raises(ValueError, match="budget"):
        check_budgets(budgets)
    with pytest.raises(ValueError, match="budget"):
        control_point_comparison([range(0, 1)], budgets)


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--budgets", "0.25,1.5"], "in (0, 1], got 1.5"),
        (["--budgets", "a quarter"], "--budgets 'a quarter'"),
        (["--pairs", "0"], "--pairs must be in 1..50"),
    ],
)
def test_the_script_rejects_bad_budgets_and_pairs_before_registering(argv, message, capsys):
    with pytest.raises(SystemExit):
        load_script().main(argv)
    assert message in capsys.readouterr().err
