"""Every kind of committed picture, drawn from small inputs: no two texts overlap and every data axis carries its
quantity with a unit in brackets (issue 40). Rendered env frames are checked on the boxes of the texts they draw."""

import itertools
import json
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from mrclam_synthetic import MODEL

from infonav_gym.registry import make_env, registered_envs
from infonav_gym.scene import RobotDrawing, SceneFrame

pytest.importorskip("matplotlib")
pygame = pytest.importorskip("pygame")

from infonav_gym.rendering import Renderer, overlap  # noqa: E402

RESULTS = Path(__file__).resolve().parents[1] / "results"
UNIT = re.compile(r"\[[^\]]+\]")


def texts_of(figure) -> list:
    """Every drawn, non-empty text of ``figure``: its titles and texts, its legends', and of each axes shown its
    titles, axis labels, tick labels in view, offset texts, annotations and legend."""
    texts = [*figure.texts, *(text for legend in figure.legends for text in [*legend.texts, legend.get_title()])]
    for axes in figure.axes:
        texts += [axes.title, axes._left_title, axes._right_title, *axes.texts]
        if axes.get_legend():
            texts += [*axes.get_legend().texts, axes.get_legend().get_title()]
        if axes.axison:
            for axis in filter(lambda axis: axis.get_visible(), axes._axis_map.values()):  # a twin's shared axis: not
                ticks = axis._update_ticks()  # the ticks in view, as drawn
                texts += [
                    axis.label,
                    axis.offsetText,
                    *(label for tick in ticks for label in (tick.label1, tick.label2)),
                ]
    unique = {id(text): text for text in texts}.values()
    return [text for text in unique if text.get_visible() and text.get_text().strip()]


def drawn(figure):
    """Draw ``figure`` with Agg (the figures are built without pyplot); its renderer."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    return canvas.get_renderer()


def assert_readable(figure) -> None:
    """(a) no two visible texts of ``figure`` overlap; (b) each data axes has a y-label, and an x-label if it has
    one, with a unit in brackets (3D axes: the z-label too)."""
    renderer = drawn(figure)
    boxes = [(text.get_text(), text.get_window_extent(renderer)) for text in texts_of(figure)]
    clashes = [(a, b) for (a, box_a), (b, box_b) in itertools.combinations(boxes, 2) if box_a.overlaps(box_b)]
    assert not clashes, f"overlapping texts: {clashes[:5]}"
    for axes in figure.axes:
        if not axes.axison or axes.get_label() == "<colorbar>":
            continue
        labels = [axes.get_ylabel()] + [axes.get_xlabel()] * bool(axes.get_xlabel())
        labels += [axes.get_zlabel()] if hasattr(axes, "get_zlabel") else []
        for label in labels:
            assert UNIT.search(label), f"axis label {label!r} has no [unit] (axes titled {axes.get_title()!r})"


def assert_frame_readable(renderer: Renderer, image: np.ndarray) -> None:
    """No two texts of the last frame ``renderer`` drew overlap, and each lies inside the image."""
    boxes = renderer.text_boxes
    assert boxes, "the frame draws text"
    clashes = [(a, b) for (a, box_a), (b, box_b) in itertools.combinations(boxes, 2) if overlap(box_a, box_b)]
    assert not clashes, f"overlapping frame texts: {clashes}"
    height, width = image.shape[:2]
    assert all(0 <= left and left + w <= width and 0 <= top and top + h <= height for _, (left, top, w, h) in boxes)


def piled_frame(step: int) -> SceneFrame:
    """Four robots nearly on one spot (as at step 0 of a team episode), long labels, landmarks side by side and
    GPS-denied discs reaching past the field's edges."""
    robots = [
        RobotDrawing(
            true_pose=np.array([16.0 + 0.1 * k + 0.2 * step, 16.0 - 0.1 * k, 0.3 * k]),
            estimated_pose=np.array([16.1 + 0.1 * k + 0.2 * step, 16.0, 0.3 * k]),
            pose_covariance=np.diag([0.05, 0.05, 0.01]),
            label=f"robot_{k}{', no GPS' if k >= 2 else ''}",
        )
        for k in range(4)
    ]
    return SceneFrame(
        bounds=(0.0, 0.0, 20.0, 20.0),
        walls=[((0.0, 0.0), (20.0, 0.0))],
        landmarks=np.array([[4.0, 4.0], [4.3, 4.1], [4.6, 3.9], [16.5, 16.5]]),
        robots=robots,
        observations=[(0, 1)],
        gps_denied_zones=[
            SimpleNamespace(center=(19.0, 1.0), radius=4.0),
            SimpleNamespace(center=(1.0, 18.0), radius=3.0),
        ],
        caption=f"t = {step} s   2 teammate and 1 landmark observations this step",
    )


def test_a_frame_of_piled_robots_has_no_overlapping_labels_and_discs_stay_inside_the_field():
    renderer = Renderer("rgb_array", 600)
    frame = piled_frame(0)
    image = renderer.draw(frame)
    assert_frame_readable(renderer, image)
    texts = [text for text, _ in renderer.text_boxes]
    assert all(f"robot_{k}" in " ".join(texts) for k in range(4)), "every robot is named"
    assert {"#1", "#2", "#3", "#4"} <= set(texts)
    assert "landmark in sight, numbered #1-#4" in texts and not any("#k" in text for text in texts)
    assert re.fullmatch(r"\d+(\.\d+)? m", texts[-1]) or any(re.fullmatch(r"\d+ m", text) for text in texts), "scale"
    layout = renderer.layout(frame)
    (left, top, width, height), (_, scene_top, _, scene_height) = layout.field, layout.scene_clip
    outside = np.zeros(image.shape[:2], bool)
    outside[scene_top : scene_top + scene_height] = True  # the scene and its margin ...
    outside[top : top + height, left : left + width] = False  # ... but the field
    canopy = np.all(image == (222, 238, 214), axis=2)
    assert canopy[~outside].any() and not canopy[outside].any(), "GPS-denied discs are clipped to the field"


def test_an_episode_strip_shows_frames_at_their_own_pixels_with_legible_titles():
    from infonav_gym.experiments.render_episode import RenderedEpisode, figure_strip

    renderer = Renderer("rgb_array", 600)
    frames = [renderer.draw(piled_frame(step)) for step in range(3)]
    assert_frame_readable(renderer, frames[-1])
    figure = figure_strip(RenderedEpisode(frames, [0, 1, 2], 10.0), "cooperative_exploration_v0, planner, seed 0")
    assert_readable(figure)
    assert figure.get_figwidth() * figure.dpi == pytest.approx(3 * frames[0].shape[1]), "one frame pixel, one pixel"
    assert min(text.get_fontsize() for text in texts_of(figure)) >= 10


def test_every_declared_metric_has_a_title_with_a_unit():
    for entry in registered_envs():
        env = make_env(entry.id)
        try:
            for metric in env.unwrapped.episode_metrics:
                assert UNIT.search(metric.title), f"{entry.id}: metric {metric.name} titled {metric.title!r}"
        finally:
            env.close()


def test_a_learning_curve_names_its_metric_and_return_with_units(tmp_path):
    pytest.importorskip("sb3_contrib")
    from agents.learning_curve import VALIDATION_CSV, append_row, figure_curve, start_curve

    path = start_curve(tmp_path, "infonav/ActiveLocalization-v0", {})
    for steps in (1000, 2000, 3000):
        append_row(path, steps, -7.0 + steps / 1000, steps / 4000, 10)
    (tmp_path / VALIDATION_CSV).write_text("steps,metric,episodes,kept\n1000,0.2,20,1\n3000,0.6,20,1\n")
    figure = figure_curve(tmp_path, "infonav/ActiveLocalization-v0: MaskablePPO, seed 0", {"greedy": 0.1})
    assert_readable(figure)
    assert [axes.get_ylabel() for axes in figure.axes] == ["mean episode return [nats]", "success rate [-]"]


def evaluation_results() -> dict:
    """Three agents, 6 episodes: a 0/1 rate and a metric with a unit, as ``evaluate`` returns them."""
    from infonav_gym.envs.metrics import EXPLORATION_METRICS
    from infonav_gym.experiments.intervals import summary_of

    metrics = {metric.name: metric for metric in EXPLORATION_METRICS[:2] + EXPLORATION_METRICS[-1:]}
    generator = np.random.default_rng(0)
    agents = {}
    for name in ("random", "greedy", "ppo:results/models/x/model.zip"):
        episodes = [{"success_rate": float(generator.random() < 0.5), "failure_rate": 0.0,
                     "episode_steps": float(generator.integers(50, 200))} for _ in range(6)]  # fmt: skip
        summary = {key: summary_of(metric, [e[key] for e in episodes]) for key, metric in metrics.items()}
        agents[name] = {"episodes": episodes, "summary": summary}
    titles = {key: metric.title for key, metric in metrics.items()}
    return {"env_id": "cooperative_exploration_v0", "episodes": 6, "metrics": titles, "agents": agents}


def test_an_evaluation_plot_draws_rates_as_points_with_wilson_intervals_and_its_legend_off_the_data():
    from infonav_gym.experiments.evaluation_files import figure_results

    figure = figure_results(evaluation_results())
    assert_readable(figure)
    rate, _, steps = figure.axes
    assert rate.get_legend_handles_labels()[1] == ["rate, 95% CI (Wilson score)"], "a rate: no box plot"
    assert "mean, 95% CI (Student t)" in steps.get_legend_handles_labels()[1]
    assert_legends_off_the_axes(figure)


def assert_legends_off_the_axes(figure) -> None:
    renderer = drawn(figure)
    legends = figure.legends + [axes.get_legend() for axes in figure.axes if axes.get_legend()]
    assert legends
    for legend, axes in itertools.product(legends, figure.axes):
        assert not legend.get_window_extent(renderer).overlaps(axes.get_window_extent(renderer)), "legend on data"


def test_the_throughput_plot_has_a_curve_per_vector_env_and_its_legend_beside_the_axes():
    from infonav_gym.experiments.benchmark import SINGLE_CARTPOLE_FIGURE, figure_throughput

    curves = ["landmark_selection_vector", "active_localization_vector", "sensor_selection_vector",
              "range_registration_vector", "cooperative_localization_vector", "cooperative_exploration_vector",
              "cartpole_vector", "vmas_navigation"]  # fmt: skip
    figures = {f"{curve}_{n}_steps_per_s": 1e3 * (k + 1) * n**0.8 for k, curve in enumerate(curves) for n in (1, 16)}
    figure = figure_throughput({**figures, SINGLE_CARTPOLE_FIGURE: 1.7e5})
    assert_readable(figure)
    assert_legends_off_the_axes(figure)
    assert set(curves) <= set(figure.axes[0].get_legend_handles_labels()[1])


def test_the_committed_throughput_plot_is_made_by_the_command_results_readme_names():
    readme = (RESULTS / "README.md").read_text()
    assert re.search(r"\| `throughput.png` \| `infonav benchmark [^`]*--plot results/throughput.png", readme)


def test_the_paper_figures_are_readable(tmp_path):
    from infonav_gym.experiments.demo import figure_information_field
    from infonav_gym.experiments.reproduce.fig3 import figure_fig3
    from infonav_gym.experiments.reproduce.fig5 import figure_fig5

    assert_readable(figure_information_field(seed=0, resolution=8))
    assert_readable(figure_fig3(json.loads((RESULTS / "fig3.json").read_text())["fig3"]))
    fig5 = json.loads((RESULTS / "fig5.json").read_text())["fig5"]
    fig5["views"] = fig5["views"][:1]  # one row of four panels is the kind
    generator = np.random.default_rng(0)
    images = [
        {key: generator.integers(0, 256, view[key]["shape"]) for key in ("camera", "ladar")} for view in fig5["views"]
    ]
    assert_readable(figure_fig5(fig5, images))


def test_the_fig6_frame_pair_plot_is_readable():
    from infonav_gym.experiments.reproduce.fig6 import PairRegistration, figure_fig6
    from infonav_gym.registration.frame_pairs import terrain_frame_pair

    pair = terrain_frame_pair(np.random.default_rng(0))
    registration = PairRegistration(pair)()
    assert_readable(figure_fig6(pair, registration["transform"], registration))


def test_the_replay_and_registration_plots_are_readable():
    from infonav_gym.datasets.noise_model import NoiseModel
    from infonav_gym.experiments.registration_recall import figure_comparison
    from infonav_gym.experiments.replay.plots import figure_calibration, figure_nees_over_time

    generator = np.random.default_rng(0)
    rows = {"range": generator.uniform(0.5, 5.0, 300), "bearing": generator.uniform(-0.5, 0.5, 300)}
    rows |= {"range_error": generator.normal(0, 0.1, 300), "bearing_error": generator.normal(0, 0.02, 300)}
    assert_readable(figure_calibration(NoiseModel(robots={1: MODEL}, pooled=MODEL, source="test"), {1: rows}))
    series = {"time_s": np.arange(50.0), "nees": generator.chisquare(3, 50)}
    robot = {"nees_over_time": series, "mean_nees": 3.1, "nees_fraction_inside_95": 0.9}
    assert_readable(figure_nees_over_time({"robots": {1: robot, 2: robot}}))
    assert_readable(figure_comparison(json.loads((RESULTS / "registration_recall.json").read_text())["control_points"]))


def test_the_committed_evaluation_with_the_longest_agent_names_is_readable():
    from infonav_gym.experiments.evaluation_files import figure_results

    evaluations = [json.loads(path.read_text()) for path in sorted(RESULTS.glob("*.json"))]
    evaluations = [results for results in evaluations if "agents" in results]
    longest = max(evaluations, key=lambda results: (sum(map(len, results["agents"])), len(results["metrics"])))
    assert_readable(figure_results(longest))
