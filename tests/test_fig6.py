"""``infonav reproduce fig6``: consecutive terrain frames before and after ICP, and the seed statistics."""

import json

import pytest

from infonav_gym.experiments.cli import main


def test_reproduce_fig6_writes_the_figure_and_json_whose_errors_say_icp_registered_the_frames(tmp_path, capsys):
    assert main(["reproduce", "fig6", "--seeds", "2", "--output-dir", str(tmp_path), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    saved = json.loads((tmp_path / "fig6.json").read_text())
    assert (tmp_path / "fig6.png").stat().st_size > 10_000
    assert printed["fig6"] == saved["fig6"]
    plotted = saved["fig6"]["registration"]
    assert plotted["error_after_m"] < 0.5 * plotted["error_before_m"]
    assert plotted["points"] > 1000 and 1 <= plotted["iterations"] <= 50
    methods = saved["seed_statistics"]["methods"]
    assert set(methods) == {"all", "entropy", "uniform", "random"}
    quarter = methods["all"]["mean_points"] * saved["seed_statistics"]["control_fraction"]
    for name in ("entropy", "uniform", "random"):
        assert methods[name]["mean_points"] == pytest.approx(quarter, rel=0.01)
        assert methods[name]["mean_error_before_m"] == methods["all"]["mean_error_before_m"]
    assert saved["seed_statistics"]["seeds"] == [0, 1]


def test_reproduce_fig6_prints_a_summary_table(tmp_path, capsys):
    assert main(["reproduce", "fig6", "--seeds", "1", "--output-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "Fig. 6, seed 0" in out and "entropy" in out and str(tmp_path / "fig6.json") in out
