"""Keeping the best policy on validation seeds (``agents.validation``): its episodes are the ones ``infonav evaluate``
plays, and the policy kept is the one whose validation was best."""

import csv
import json

import numpy as np
import pytest

pytest.importorskip("sb3_contrib")

import torch  # noqa: E402

import infonav_gym  # noqa: E402, F401  (registers the envs)
from agents.ppo import build_model, load_model, save_policy, train, training_vec_env  # noqa: E402
from agents.validation import BEST_DIR, VALIDATION_SEEDS, validation_metrics  # noqa: E402
from infonav_gym.envs.traits import main_metric_of  # noqa: E402
from infonav_gym.experiments.cli import main  # noqa: E402
from infonav_gym.experiments.evaluation import evaluate  # noqa: E402
from infonav_gym.registry import make_env  # noqa: E402

LANDMARK_ID = "infonav/LandmarkSelection-v0"
SMALL = {"n_steps": 32, "batch_size": 32, "n_epochs": 1}


def evaluated_metrics(env_id: str, config: dict, model_dir, episodes: int, seed: int) -> list[float]:
    """The main metric of each episode ``infonav evaluate`` plays with the saved policy."""
    env = make_env(env_id, **config)
    name = main_metric_of(env).name
    env.close()
    results = evaluate(env_id, [f"ppo:{model_dir}"], episodes, seed, config, progress=False)
    return [episode[name] for episode in results["agents"][f"ppo:{model_dir}"]["episodes"]]


@pytest.mark.parametrize(
    "env_id, config, vectorization",
    [
        (LANDMARK_ID, {"horizon": 12}, "native"),
        # episodes of different lengths: copies that ended early go on, but only their first episode counts
        ("infonav/ActiveLocalization-v0", {"horizon": 40, "goal_radius_m": 25.0, "max_position_std_m": 0.3}, "sync"),
        ("cooperative_localization_v0", {"max_cycles": 5}, None),
        ("cooperative_exploration_v0", {"max_cycles": 12, "max_position_std_m": 0.3, "observe_gains": True}, None),
    ],
)
def test_validation_plays_the_episodes_infonav_evaluate_plays(tmp_path, env_id, config, vectorization):
    model = build_model(env_id, seed=3, n_envs=2, hyperparameters={**SMALL, "normalize": {}}, env_kwargs=config)
    model.learn(64)  # statistics that normalize the observations, and a policy that is not the initial one
    save_policy(model, tmp_path)
    copies = training_vec_env(env_id, 4, 0, config, vectorization)[1]
    validated = validation_metrics(model, copies, 4, 11, model.get_env())
    assert validated.tolist() == evaluated_metrics(env_id, config, tmp_path, 4, 11)


LANDMARK_CONFIG = {"horizon": 12}


def small_run(output, **validation):
    train(
        LANDMARK_ID,
        320,
        seed=2,
        n_envs=2,
        output_dir=output,
        hyperparameters=SMALL,
        progress=False,
        checkpoints=0,
        env_kwargs=LANDMARK_CONFIG,
        **validation,
    )
    return output


@pytest.fixture(scope="module")
def validated_run(tmp_path_factory):
    return small_run(tmp_path_factory.mktemp("validated"), validation_episodes=6, validation_every=128)


def test_validating_leaves_the_training_as_it_is(validated_run, tmp_path):
    """The validations draw on no generator of the training: the same curve and the same final policy."""
    plain = small_run(tmp_path)
    assert (plain / "curve.csv").read_text() == (validated_run / "curve.csv").read_text()
    trained = [load_model(run).policy.state_dict() for run in (plain, validated_run)]
    for name, value in trained[0].items():
        assert torch.equal(value, trained[1][name]), name


def test_validations_run_at_the_start_every_so_many_steps_and_at_the_end(validated_run):
    with (validated_run / "validation.csv").open(newline="") as file:
        header, *rows = list(csv.reader(file))
    assert header == ["steps", "mean_metric", "episodes", "kept"]
    assert [int(row[0]) for row in rows] == [0, 128, 256, 320]  # rollouts of 64 steps: once 128 passed, and the end
    assert {row[2] for row in rows} == {"6"}


def test_the_kept_policy_is_the_first_best_and_validates_to_what_the_run_recorded(validated_run):
    with (validated_run / "validation.csv").open(newline="") as file:
        rows = [(int(steps), float(mean), kept == "1") for steps, mean, _, kept in list(csv.reader(file))[1:]]
    best_so_far = -np.inf
    for _, mean, kept in rows:  # kept exactly where the metric beats every earlier validation
        assert kept == (mean > best_so_far)
        best_so_far = max(best_so_far, mean)
    record = json.loads((validated_run / "train.json").read_text())["validation"]
    best_steps, best_mean, _ = next(row for row in rows if row[1] == best_so_far)
    assert (record["best_steps"], record["best_metric"]) == (best_steps, best_mean)
    assert record["seeds"] == f"{VALIDATION_SEEDS + 2}..{VALIDATION_SEEDS + 7}"
    replayed = evaluated_metrics(LANDMARK_ID, LANDMARK_CONFIG, validated_run / BEST_DIR, 6, VALIDATION_SEEDS + 2)
    assert np.mean(replayed) == best_mean


def test_stop_at_ends_training_at_the_first_validation_that_reaches_it(validated_run, tmp_path):
    with (validated_run / "validation.csv").open(newline="") as file:
        rows = [(int(steps), float(mean)) for steps, mean, _, _ in list(csv.reader(file))[1:]]
    stop_at = rows[1][1]  # the mean of the validation at 128 steps: reached there at the latest
    first = next(steps for steps, mean in rows if mean >= stop_at)
    stopped = small_run(tmp_path, validation_episodes=6, validation_every=128, validation_stop_at=stop_at)
    record = json.loads((stopped / "train.json").read_text())
    assert (record["validation"]["stop_at"], record["validation"]["stopped_at"]) == (stop_at, first)
    assert record["timesteps"] == first + 2  # SB3 stops at the next step of its 2 copies
    with pytest.raises(ValueError, match="needs validation episodes"):
        small_run(tmp_path / "none", validation_stop_at=1.0)


def test_the_curve_shows_the_validations(validated_run):
    image = pytest.importorskip("matplotlib.image").imread(validated_run / "curve.png")
    assert image.shape[:2] == (600, 700)  # the return and metric panels, the validations on the second


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--eval-episodes", "4", "--backend", "rllib"], "--eval-episodes keeps the best SB3 policy"),
        (["--eval-every", "100"], "--eval-every needs --eval-episodes"),
        (["--stop-at", "1"], "--stop-at needs --eval-episodes"),
        (["--stop-at", "1", "--backend", "rllib"], "--stop-at stops SB3's training"),
    ],
)
def test_a_bad_validation_request_is_one_line_exit_2(tmp_path, capsys, flags, message):
    with pytest.raises(SystemExit) as exit_info:
        main(["train", "--env", LANDMARK_ID, "--timesteps", "64", "--output", str(tmp_path / "m"), *flags])
    assert exit_info.value.code == 2
    assert message in capsys.readouterr().err
