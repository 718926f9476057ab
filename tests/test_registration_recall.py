"""Issue 26's control-point comparison on ``results/registration_recall.json`` (five sets of 50 terrain pairs).

The committed tables are made by ``python scripts/registration_recall.py`` (see ``results/README.md`` for how
long it takes); the suite re-registers the first pair of each set and checks the errors against them (the
times are the machine's), then judges the tables: the default registration by recall, and "entropy" against
the field's standard selectors at a quarter of the returns, by recall and median. The harness itself runs
on one pair per set at small budgets.
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
from infonav_gym.registration.frame_pairs import FRAME_PAIR_ICP

ROOT = Path(__file__).resolve().parents[1]
RESULT = ROOT / "results" / "registration_recall.json"
SCRIPT = ROOT / "scripts" / "registration_recall.py"
ACCEPTANCE_BUDGET = budget_label(0.25)
STANDARD_SELECTORS = ("random", "uniform", "normal_space", "covariance")


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


def _entropy_against_the_standard_selectors(comparison) -> str:
    """Per seed set at the acceptance budget: entropy's 5 cm recall and median, and the standard selectors'."""
    selectors = comparison["by_budget"][ACCEPTANCE_BUDGET]
    rows = []
    for index in range(len(comparison["all"])):
        figures = {name: selectors[name][index] for name in ("entropy", *STANDARD_SELECTORS)}
        rows.append(
            ", ".join(
                f"{name} {100 * row['recall_5cm']:.0f}% {1e3 * row['median_error_after_m']:.1f} mm"
                for name, row in figures.items()
            )
        )
    return "; ".join(rows)


@pytest.mark.xfail(
    reason="not reached (a strict xfail: passing would mean the criterion now holds and the mark must go): "
    "at 25 % entropy's 5 cm recall is below a standard selector's on sets 0-349 (96, 96, 92, 96 % against "
    "uniform's 98, 98, 96, 100 %) and its median above the lowest on sets 100-449 (7.73, 9.51, 8.56, 9.05 mm "
    "against 7.68, 7.92, 7.48, 8.06 mm; on set 0-49 it is the lowest, 7.90 against 8.38 mm); random beats it "
    "on recall on four sets; entropy is not tuned to these seeds (issue 26: improving it is a later step)",
    strict=True,
)
def test_entropy_recall_and_median_are_at_least_every_standard_selectors_at_a_quarter_on_every_set(comparison):
    selectors = comparison["by_budget"][ACCEPTANCE_BUDGET]
    measured = _entropy_against_the_standard_selectors(comparison)
    for index, entropy in enumerate(selectors["entropy"]):
        for name in STANDARD_SELECTORS:
            other = selectors[name][index]
            assert entropy["recall_5cm"] >= other["recall_5cm"], (index, name, measured)
            assert entropy["median_error_after_m"] <= other["median_error_after_m"], (index, name, measured)


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
