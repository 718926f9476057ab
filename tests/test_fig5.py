"""The paper's Fig. 5: LADAR images carry more information than camera images on vegetated, rugged terrain,
and the reverse in front of a building (information is scene-specific)."""

import json
import math

import numpy as np
import pytest
from skimage.measure import shannon_entropy

from infonav_gym.experiments.cli import main
from infonav_gym.experiments.reproduce.fig5 import (
    SECOND_VIEW_ADVANCE_M,
    SECOND_VIEW_TURN_RAD,
    level_heading,
    run_fig5,
)
from infonav_gym.information import histogram_entropy
from infonav_gym.world.terrain import Terrain


@pytest.fixture(scope="module")
def fig5_seed_0():
    return run_fig5(seed=0)


def entropies(view: dict) -> tuple[float, float]:
    return view["camera"]["entropy_nats"], view["ladar"]["entropy_nats"]


def test_both_similar_paper_like_views_give_the_ladar_more_entropy_than_the_camera(fig5_seed_0):
    record, _ = fig5_seed_0
    first, second = record["views"][:2]
    assert first["case"] == second["case"] == "paper_like"
    for view in (first, second):
        camera, ladar = entropies(view)
        assert ladar > camera + 0.1, view["label"]
    (x0, y0, heading0), (x1, y1, heading1) = first["vehicle_pose"], second["vehicle_pose"]
    assert math.hypot(x1 - x0, y1 - y0) == pytest.approx(SECOND_VIEW_ADVANCE_M)
    assert heading1 - heading0 == pytest.approx(SECOND_VIEW_TURN_RAD)


def test_a_building_close_ahead_gives_the_camera_more_entropy_than_the_ladar(fig5_seed_0):
    record, _ = fig5_seed_0
    view = record["views"][2]
    assert view["case"] == "building_ahead"
    camera, ladar = entropies(view)
    assert camera > ladar + 0.5
    assert 3.0 <= record["building"]["distance_m"] <= 8.0


def test_entropies_are_eqs_4_5_of_the_images_and_agree_with_scikit_image(fig5_seed_0):
    record, images = fig5_seed_0
    shapes = {"camera": [120, 160], "ladar": [32, 180]}  # the default sensors
    for view, pair in zip(record["views"], images, strict=True):
        for sensor, image in pair.items():
            assert image.dtype == np.uint8 and list(image.shape) == shapes[sensor] == view[sensor]["shape"]
            expected = shannon_entropy(image, base=np.e)
            assert histogram_entropy(image) == pytest.approx(expected, rel=1e-12, abs=1e-12)
            assert view[sensor]["entropy_nats"] == pytest.approx(expected, rel=1e-12, abs=1e-12)


def test_level_heading_follows_the_contour_of_a_tilted_plane():
    x = np.arange(41) * 1.0 - 20.0
    slope_along_x = Terrain(np.tile(0.3 * x, (41, 1)), origin_m=(-20.0, -20.0), cell_m=1.0)
    heading = level_heading(slope_along_x, (0.0, 0.0))
    assert abs(math.sin(heading)) == pytest.approx(1.0), f"heading {math.degrees(heading)} deg is not along y"


def test_reproduce_fig5_writes_the_plot_and_the_json_it_prints(capsys, tmp_path):
    pytest.importorskip("matplotlib")
    argv = ["reproduce", "fig5", "--seeds", "2", "--output-dir", str(tmp_path), "--json"]
    assert main(argv) == 0
    printed = json.loads(capsys.readouterr().out)
    written = json.loads((tmp_path / "fig5.json").read_text())
    assert written == printed
    assert written["command"] == "infonav " + " ".join(argv)
    assert written["files"] == [str(tmp_path / "fig5.png"), str(tmp_path / "fig5.json")]
    assert (tmp_path / "fig5.png").stat().st_size > 50_000
    assert written["scenes"]["paper_like"]["make_terrain"]["roughness"] > 0.5
    views = written["fig5"]["views"]
    assert [view["label"] for view in views] == ["paper-like scene 1", "paper-like scene 2", "building ahead"]
    for view in views:  # the histograms and entropies drawn in the plot
        for sensor in ("camera", "ladar"):
            counts = np.array(view[sensor]["histogram"])
            assert counts.shape == (256,) and counts.sum() == math.prod(view[sensor]["shape"])
            p = counts[counts > 0] / counts.sum()
            assert view[sensor]["entropy_nats"] == pytest.approx(-np.sum(p * np.log(p)), rel=1e-12)
    statistics = written["seed_statistics"]
    assert statistics["seeds"] == [0, 1] and [record["seed"] for record in statistics["per_seed"]] == [0, 1]
    first = statistics["per_seed"][0]
    assert [view["ladar"] for view in first["paper_like"]] == [view["ladar"]["entropy_nats"] for view in views[:2]]
    assert first["building_ahead"][0]["camera"] == views[2]["camera"]["entropy_nats"]
    ladar_wins = [all(v["ladar"] > v["camera"] for v in record["paper_like"]) for record in statistics["per_seed"]]
    assert statistics["paper_like"]["fraction"] == np.mean(ladar_wins)
    assert statistics["paper_like"]["expected"] == "LADAR > camera"


def test_reproduce_fig5_prints_the_summary_table(capsys, tmp_path):
    pytest.importorskip("matplotlib")
    assert main(["reproduce", "fig5", "--seeds", "1", "--output-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "paper-like scene 1" in out and "building ahead" in out and "camera more informative" in out
    assert "LADAR > camera   in 100.0% of seeds" in out and str(tmp_path / "fig5.png") in out
