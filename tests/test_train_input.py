"""``infonav train``'s input checked before any work: hyperparameters, options per backend, --timesteps against the
rollout, --init-from-planner files, Ray addresses; nothing half-written, no temp folders left behind."""

import contextlib
import socket
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import unused_address

pytest.importorskip("sb3_contrib")

import agents.ppo  # noqa: E402
from agents.imitation import Demonstrations  # noqa: E402
from agents.learning_curve import CURVE_CSV, CURVE_PNG, drawn_curve  # noqa: E402
from agents.ppo import build_model, load_hyperparameters, planned_steps  # noqa: E402
from agents.ray_support import check_reachable  # noqa: E402
from infonav_gym.experiments.cli import main  # noqa: E402

LANDMARK_ID = "infonav/LandmarkSelection-v0"
ROOT = Path(__file__).resolve().parents[1]
TINY = {"n_envs": 1, "n_steps": 8, "batch_size": 8, "n_epochs": 1}  # one 8-step rollout


def refused(capsys, argv) -> str:
    """``infonav ARGV`` exits 2 with one line on stderr and no traceback, before any work; the line."""
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    out, err = capsys.readouterr()
    assert exit_info.value.code == 2 and "Traceback" not in err and len(err.splitlines()) == 1, err
    assert err.startswith(f"infonav {argv[0]}: error: ")
    return err.strip()


@contextlib.contextmanager
def http2_server(status: bytes | None):
    """``127.0.0.1:PORT`` of a server that answers any HTTP/2 request with a SETTINGS frame, then response headers
    starting with the HPACK byte ``status`` (``b"\\x88"``: 200, a gRPC server; ``b"\\x8d"``: 404, an HTTP proxy);
    ``None``: it accepts connections and never answers."""
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen()

        def answer():
            connection, _ = listener.accept()
            with connection:
                connection.recv(4096)
                connection.sendall(bytes(3) + b"\x04" + bytes(5) + b"\x00\x00\x01\x01\x05\x00\x00\x00\x01" + status)

        thread = threading.Thread(target=answer, daemon=True)
        if status is not None:
            thread.start()
        yield f"127.0.0.1:{listener.getsockname()[1]}"
        if status is not None:
            thread.join(timeout=5)


def test_a_grpc_server_passes_the_ray_address_check():
    with http2_server(b"\x88") as address:
        check_reachable(address)


@pytest.mark.parametrize(
    ("address", "message"),
    [
        (unused_address, "(Connection refused)"),
        (lambda: http2_server(None), "it did not answer within 1 s"),
        (lambda: http2_server(b"\x8d"), "the port answers, but not as Ray's gRPC server"),  # e.g. an HTTP/2 proxy
    ],
    ids=["refused", "silent", "http-proxy"],
)
def test_an_address_without_a_ray_cluster_is_refused_within_seconds(address, message):
    with address() as where:
        start = time.perf_counter()
        with pytest.raises(ValueError, match=f"^cannot reach a Ray cluster at '{where}'") as error:
            check_reachable(where, timeout_s=1.0)
    assert message in str(error.value) and time.perf_counter() - start < 2


@pytest.mark.parametrize("address", ["localhost:99999", "localhost:0", ":6379", "a:b:6379", "host:port", "ray://"])
def test_a_malformed_ray_address_is_refused_naming_it(capsys, address):
    argv = ["train", "--backend", "rllib", "--env", LANDMARK_ID, "--timesteps", "10", "--address", address]
    assert f"Ray address {address!r} is not HOST:PORT with a port from 1 to 65535" in refused(capsys, argv)


def test_train_refuses_an_http_proxy_as_a_ray_cluster_in_one_line(capsys):
    with http2_server(b"\x8d") as address:
        argv = ["train", "--backend", "rllib", "--env", LANDMARK_ID, "--timesteps", "10", "--address", address]
        assert "not as Ray's gRPC server" in refused(capsys, argv)


@pytest.fixture
def no_work(monkeypatch):
    """Building the training envs or a model, or starting Ray, fails the test: the input must be refused before."""

    def fail(*args, **kwargs):
        raise AssertionError("work started before the input was checked")

    for name in ("training_vec_env", "build_model"):
        monkeypatch.setattr(agents.ppo, name, fail)
    ray = pytest.importorskip("ray")
    monkeypatch.setattr(ray, "init", fail)


def hyperparams_file(tmp_path, text: str) -> Path:
    path = tmp_path / "ppo.yml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("backend", ["sb3", "rllib"])
@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("gamma: nan", "gamma must be a number in [0, 1], got 'nan'"),
        ("gamma: .nan", "gamma must be a number in [0, 1], got nan"),
        ("gamma: 7", "gamma must be a number in [0, 1], got 7"),
        ("gae_lambda: -0.1", "gae_lambda must be a number in [0, 1], got -0.1"),
        ("batch_size: 0", "batch_size must be an integer >= 2, got 0"),
        ("n_steps: -16", "n_steps must be an integer from 1 to 65536, got -16"),
        ("n_epochs: 2.5", "n_epochs must be an integer >= 1, got 2.5"),
        ("n_envs: 100000", "n_envs must be an integer from 1 to 4096, got 100000"),
        ("learning_rate: .inf", "learning_rate must be a finite number > 0 or lin_<start> with such a start, got inf"),
        ("learning_rate: lin_-1", "learning_rate must be a finite number > 0 or lin_<start>"),
        ("clip_range: 1.5", "clip_range must be a number in (0, 1] or lin_<start> with such a start, got 1.5"),
        ("ent_coef: -0.01", "ent_coef must be a finite number >= 0, got -0.01"),
        ("max_grad_norm: 0", "max_grad_norm must be a finite number > 0, got 0"),
        ("policy_kwargs: [64, 64]", "policy_kwargs must be a mapping with keys from net_arch, activation_fn"),
        ("policy_kwargs: {net_arch: big}", "policy_kwargs.net_arch must be a list of layer widths from 1 to 4096"),
        ("policy_kwargs: {net_arch: [64, 0]}", "policy_kwargs.net_arch must be a list of layer widths"),
        ("policy_kwargs: {activation_fn: gelu}", "policy_kwargs.activation_fn must be one of tanh, relu, got 'gelu'"),
        ("policy_kwargs: {width: 3}", "unknown hyperparameter 'width' of policy_kwargs: the keys are net_arch"),
        ("normalize: yes please", "normalize must be true or false, or a mapping with keys from norm_obs"),
        ("normalize: {clip_obs: 0}", "normalize.clip_obs must be a finite number > 0, got 0"),
        ("policy: CnnPolicy", "policy must be one of MlpPolicy, got 'CnnPolicy'"),
        ("seed: 3", "unknown hyperparameter 'seed': the keys are n_envs, policy"),
    ],
)
def test_a_hyperparameter_out_of_range_is_one_line_naming_file_block_key_and_range(
    capsys, tmp_path, no_work, backend, line, message
):
    file = hyperparams_file(tmp_path, f"default:\n  n_steps: 16\n  {line}\n")
    output = tmp_path / "out"
    argv = ["train", "--backend", backend, "--env", LANDMARK_ID, "--timesteps", "64", "--output", str(output)]
    error = refused(capsys, [*argv, "--hyperparams", str(file)])
    assert message in error and error.endswith(f"(block 'default' of hyperparameter file {file})")
    assert not output.exists()


def test_numbers_yaml_reads_as_strings_are_numbers(tmp_path):
    file = hyperparams_file(tmp_path, "default:\n  learning_rate: 3e-4\n  clip_range: lin_2e-1\n  target_kl: null\n")
    assert load_hyperparameters(LANDMARK_ID, file) == {
        "learning_rate": 3e-4,
        "clip_range": "lin_2e-1",
        "target_kl": None,
    }


def test_the_shipped_and_the_committed_blocks_pass_the_check():
    shipped = yaml.safe_load((ROOT / "agents" / "hyperparams" / "ppo.yml").read_text())
    assert all(load_hyperparameters(env_id) == block for env_id, block in shipped.items() if env_id != "default")
    for file in (ROOT / "results" / "hyperparams").glob("*.yml"):
        for env_id, block in yaml.safe_load(file.read_text()).items():
            assert load_hyperparameters(env_id, file) == block


def test_rllib_refuses_a_schedule_it_cannot_translate(capsys, tmp_path, no_work):
    file = hyperparams_file(tmp_path, "default:\n  learning_rate: lin_3e-4\n")
    argv = ["train", "--backend", "rllib", "--env", LANDMARK_ID, "--timesteps", "64", "--hyperparams", str(file)]
    assert "hyperparameter(s) ['learning_rate'] are schedules: rllib takes numbers" in refused(capsys, argv)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (
            ["--env", LANDMARK_ID, "--timesteps", "4000"],
            "--timesteps 4000 is less than one rollout of 4096 env steps (n_steps 64 x n_envs 64): PPO learns from",
        ),
        (
            ["--env", "cooperative_localization_v0", "--timesteps", "8000", "--n-envs", "64"],
            "--timesteps 8000 is less than one rollout of 8192 env steps (n_steps 32 x n_envs 64 x 4 robots)",
        ),
    ],
)
def test_timesteps_below_one_rollout_are_refused_naming_the_rollout(capsys, tmp_path, monkeypatch, argv, message):
    monkeypatch.setattr(agents.ppo, "build_model", None)  # never reached
    output = tmp_path / "out"
    assert message in refused(capsys, ["train", *argv, "--output", str(output)])
    assert not output.exists()


def test_a_batch_size_leaving_a_one_step_minibatch_is_refused(capsys, tmp_path, no_work):
    file = hyperparams_file(tmp_path, "default:\n  n_envs: 2\n  n_steps: 16\n  batch_size: 31\n")
    argv = ["train", "--env", LANDMARK_ID, "--timesteps", "64", "--hyperparams", str(file)]
    assert "batch_size 31 leaves a minibatch of 1 step in each rollout of 32 env steps" in refused(capsys, argv)


def test_timesteps_between_rollouts_say_in_one_line_how_many_will_be_trained(capsys):
    assert planned_steps(4000, 1024, "n_steps 64 x n_envs 16", {}) == 4096
    assert capsys.readouterr().err == (
        "note: --timesteps 4000 is not a whole number of rollouts of 1024 env steps (n_steps 64 x n_envs 16): "
        "PPO will train 4096\n"
    )
    assert planned_steps(2048, 1024, "", {}) == 2048 and planned_steps(0, 1024, "", {}) == 0  # 0: cloning alone
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize(
    ("backend", "option", "message"),
    [
        (
            "sb3",
            ["--policies", "per_robot"],
            "--policies lays out RLlib's policies in a team env: use it with --backend rllib (sb3 ignores it)",
        ),
        (
            "sb3",
            ["--num-env-runners", "0"],
            "--num-env-runners sets RLlib's env runner processes: use it with --backend rllib",
        ),
        ("sb3", ["--envs-per-runner", "2"], "--envs-per-runner sets the env copies of each RLlib env runner"),
        (
            "sb3",
            ["--address", "127.0.0.1:1"],
            "--address names the Ray cluster RLlib trains on: use it with --backend rllib",
        ),
        (
            "rllib",
            ["--vectorization", "sync"],
            "--vectorization picks how SB3 steps its env copies: use it with --backend sb3 (rllib ignores it)",
        ),
        ("rllib", ["--tensorboard"], "--tensorboard logs SB3's training: use it with --backend sb3"),
        (
            "rllib",
            ["--n-envs", "4"],
            "--n-envs sets SB3's env copies (rllib: --envs-per-runner): use it with --backend sb3",
        ),
        ("sb3", ["--workers", "2"], "--workers needs --init-from-planner (the planner episodes the workers play)"),
    ],
)
def test_an_option_the_backend_ignores_is_refused_naming_it(capsys, tmp_path, no_work, backend, option, message):
    argv = ["train", "--backend", backend, "--env", LANDMARK_ID, "--timesteps", "64", *option]
    assert message in refused(capsys, [*argv, "--output", str(tmp_path / "out")])


def test_workers_with_a_demonstrations_file_are_refused(capsys, tmp_path, no_work):
    file = tmp_path / "demonstrations.npz"
    Demonstrations(*(np.zeros((2, 1)) for _ in range(5))).save(file)
    argv = ["train", "--env", LANDMARK_ID, "--timesteps", "0", "--init-from-planner", str(file), "--workers", "2"]
    assert "--workers play the planner's episodes of --init-from-planner EPISODES" in refused(capsys, argv)


def _npz_bytes(**arrays) -> bytes:
    path = Path(tempfile.mkdtemp()) / "a.npz"
    np.savez(path, **arrays)
    return path.read_bytes()


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        (b"observations,actions\n1,2\n", "it is not an .npz (zip) file"),
        (b"", "it is not an .npz (zip) file"),
        ("wrong keys", "it has no arrays observations, action_masks, actions, returns, seeds"),
        ("truncated", "a damaged .npz"),
    ],
)
def test_init_from_planner_with_a_file_that_is_not_demonstrations_is_one_line(
    capsys, tmp_path, no_work, content, problem
):
    file = tmp_path / "demonstrations.npz"
    demonstrations = Demonstrations(*(np.zeros((2, 1)) for _ in range(5)))
    demonstrations.save(file)
    whole = file.read_bytes()
    file.write_bytes(
        {"wrong keys": _npz_bytes(a=np.ones(2)), "truncated": whole[: len(whole) // 2]}.get(content, content)
    )
    argv = ["train", "--env", LANDMARK_ID, "--timesteps", "0", "--init-from-planner", str(file)]
    error = refused(capsys, [*argv, "--output", str(tmp_path / "out")])
    assert (
        f"--init-from-planner '{file}' is not planner demonstrations ({problem}): expected the demonstrations.npz"
        in error
    )
    assert "allow_pickle" not in error and not (tmp_path / "out").exists()


def test_training_leaves_no_sb3_folder_in_the_temp_folder(tmp_path, monkeypatch):
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    model = build_model(LANDMARK_ID, hyperparameters=TINY, env_kwargs={"horizon": 4})
    model.learn(8)
    model.get_env().close()
    assert list(tmp_path.glob("SB3-*")) == []


def test_a_run_that_fails_removes_what_it_wrote_and_keeps_what_was_there(capsys, tmp_path, monkeypatch):
    def fail(model, *args, **kwargs):
        raise ValueError("the env failed mid-training")

    monkeypatch.setattr(agents.ppo.MaskablePPO, "learn", fail)
    file = hyperparams_file(tmp_path, yaml.safe_dump({"default": TINY}))
    argv = ["train", "--env", LANDMARK_ID, "--timesteps", "8", "--config", "horizon=4", "--hyperparams", str(file)]
    fresh, kept = tmp_path / "fresh", tmp_path / "kept"
    assert refused(capsys, [*argv, "--output", str(fresh)]).endswith("the env failed mid-training")
    assert not fresh.exists()
    kept.mkdir()
    (kept / "notes.txt").write_text("mine")
    refused(capsys, [*argv, "--output", str(kept)])
    assert [path.name for path in kept.iterdir()] == ["notes.txt"]


def test_a_curve_with_no_point_is_not_drawn_and_says_so(tmp_path):
    (tmp_path / CURVE_CSV).write_text("steps,mean_return,cumulative_mi,episodes\n")
    assert drawn_curve(tmp_path, "title", None) == (
        "curve.csv written; no episode ended in training, so no curve.png: nothing to draw"
    )
    assert not (tmp_path / CURVE_PNG).exists()


def test_planner_workers_are_capped_at_the_planner_episodes(capsys, tmp_path, monkeypatch):
    asked = {}

    def stop(*args, planner_workers, **kwargs):
        asked["workers"] = planner_workers
        raise ValueError("stopped before training")

    monkeypatch.setattr(agents.ppo, "train", stop)
    argv = ["train", "--env", LANDMARK_ID, "--timesteps", "0", "--init-from-planner", "2", "--workers", "8"]
    with pytest.raises(SystemExit):
        main([*argv, "--output", str(tmp_path / "out")])
    assert asked == {"workers": 2}
    assert capsys.readouterr().err.startswith("--workers 8 capped at 2: there are 2 episodes to play\n")


def test_init_from_planner_on_an_env_without_a_planner_is_refused_before_work(capsys, tmp_path, no_work):
    argv = ["train", "--env", "infonav/SensorSelection-v0", "--timesteps", "0", "--init-from-planner", "3"]
    error = refused(capsys, [*argv, "--output", str(tmp_path / "out")])
    assert (
        "PlannerAgent needs an env with a planning_model() method" in error and "SensorSelectionEnv has none" in error
    )
    assert not (tmp_path / "out").exists()


def test_a_rollout_beyond_the_available_memory_is_refused_with_its_estimate(capsys, tmp_path, no_work, monkeypatch):
    monkeypatch.setattr("infonav_gym.memory.available_bytes", lambda: 10**8)
    file = hyperparams_file(tmp_path, "default:\n  n_steps: 65536\n  n_envs: 64\n  batch_size: 4096\n")
    argv = ["train", "--env", LANDMARK_ID, "--timesteps", str(65536 * 64), "--hyperparams", str(file)]
    error = refused(capsys, [*argv, "--output", str(tmp_path / "out")])
    assert "a rollout of 4194304 env steps (n_steps 65536 x n_envs 64, 65 float32 each) needs about 1.1 GB" in error
