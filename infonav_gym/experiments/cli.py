"""The ``infonav`` command: demo, evaluate, leaderboard, render, train, dataset, clone, benchmark, reproduce, replay."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import shlex
import sys
from pathlib import Path

import infonav_gym  # registers the envs
from infonav_gym.compiled import INTERRUPTIONS, pressed_ctrl_c
from infonav_gym.experiments.arguments import (
    end_time,
    episodes_or_file,
    integer,
    names,
    number,
    seed,
)
from infonav_gym.experiments.demo import DEMO_HORIZON
from infonav_gym.experiments.episode_pool import checked_workers
from infonav_gym.experiments.episodes import AGENT_KINDS
from infonav_gym.experiments.paths import (
    Interrupted,
    OutputWriteError,
    check_output_dir,
    check_output_stem,
    output_file,
    write_failure,
)
from infonav_gym.experiments.reproduce import DEFAULT_OUTPUT_DIR, FIGURES, printed_table
from infonav_gym.experiments.reproduce import reproduce as reproduce_figure
from infonav_gym.experiments.vector_timing import DEFAULT_VECTOR_SIZES, parse_vector_sizes

DEFAULT_ENV = "infonav/LandmarkSelection-v0"
EVALUATION_SUFFIXES = (".md", ".csv", ".json", ".png")  # the files of ``evaluate --output STEM``
LEADERBOARD_SUFFIXES = (".md", ".json")  # the files of ``leaderboard --output STEM``
DEFAULT_DATASETS = Path("datasets")  # dataset --output: Minari datasets, one directory per id
DEFAULT_MODELS = Path("results/models")  # leaderboard --models: the committed models, when run in the repository
LEADERBOARD_JSON = Path("results/leaderboard.json")  # train's curve.png references, when run in the repository
CURVE_REFERENCES = ("greedy", "planner")  # the agents drawn as lines on a learning curve
REPLAY_SUFFIXES = (".md", ".json")  # the files of ``replay mrclam --output STEM``
RENDER_SUFFIXES = (".gif", ".png")  # the files of ``render --output PREFIX``
CALIBRATION_SUFFIXES = (".json", ".png")  # the files of ``replay mrclam --calibrate OUTPUT.json``
PLOT_SUFFIX = ".png"  # demo / benchmark --plot: the file written, its suffix added unless given
PYTHON_CONSTANTS = {"True": True, "False": False, "None": None}  # --config values written as in Python
DEFAULT_VECTOR_SIZES_TEXT = ",".join(map(str, DEFAULT_VECTOR_SIZES))
# The upper ends of the counts and sizes the options take; a run's memory is checked against the machine as well.
MAX_EPISODES = 1_000_000  # episodes per agent
MAX_WORKERS = 1024  # processes; also capped at the number of tasks
MAX_STEPS = 1_000_000  # render: steps of one episode
MAX_TIMESTEPS = 10**10  # train: env steps
MAX_COPIES = 65_536  # env copies of one vector env
MAX_ROUNDS = 100  # benchmark rounds
MAX_SECONDS = 600.0  # benchmark seconds per env per round
MAX_SEEDS = 10_000  # reproduce / replay seeds
MAX_ROBOT = 99  # replay: a robot's subject number
MAX_LOG_S = 1e7  # replay: a time in the log [s] (MRCLAM logs last about 1e4 s)


def _config_pair(text: str) -> tuple[str, object]:
    """``key=value`` with the value read as JSON when it parses (numbers, true/false; Python's True, False and
    None too), else as a Python float when it is one (nan, inf), else as a string."""
    key, separator, value = text.partition("=")
    if not separator or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    for read in (PYTHON_CONSTANTS.__getitem__, json.loads, float):
        with contextlib.suppress(KeyError, ValueError):  # json.JSONDecodeError is a ValueError
            return key, read(value)
    return key, value


def _vector_sizes(text: str) -> tuple[int, ...]:
    """``--vector-sizes``: argparse reports ``parse_vector_sizes``'s message."""
    try:
        return parse_vector_sizes(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None


def _stem_help(suffixes: tuple[str, ...], files: str) -> str:
    """The help of an ``--output`` stem option writing ``files``."""
    first = suffixes[0]
    return (
        f"write {files}; the name is kept whole (out/a.v2 writes out/a.v2{first}) "
        f"but for a trailing {' or '.join(suffixes)} (out/a{first} is out/a)"
    )


def _count(parser, flag: str, high: int, default: int, what: str) -> None:
    """An integer option from 1 to ``high``, its default said in its help."""
    parser.add_argument(flag, type=integer(1, high), default=default, help=f"{what} (default: {default})")


class _Parser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line on stderr, ``infonav COMMAND: error: MESSAGE`` (as ``main``'s
    are; ``replay mrclam``'s are ``infonav replay``'s), exit 2."""

    def error(self, message: str):
        self.exit(2, f"{' '.join(self.prog.split()[:2])}: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="infonav", description="Information-driven navigation environments.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {infonav_gym.__version__}")
    commands = parser.add_subparsers(dest="command", required=True)

    demo = commands.add_parser("demo", help="the paper's Fig. 2 story: which corridor landmark brings most information")
    _count(
        demo,
        "--steps",
        DEMO_HORIZON,
        12,
        f"steps per agent, of one corridor episode: at most its horizon, {DEMO_HORIZON}",
    )
    demo.add_argument(
        "--plot", type=Path, help="also write a Fig. 2-style plot to PLOT.png (.png added unless given; matplotlib)"
    )

    evaluate = commands.add_parser("evaluate", help="evaluate baseline agents with the same seeds; print a table")
    evaluate.add_argument("--env", default=DEFAULT_ENV, help=f"env id (default: {DEFAULT_ENV})")
    evaluate.add_argument(
        "--agents",
        type=names,
        default="random,greedy",
        help="comma-separated, each once (default: random,greedy): "
        + "; ".join(f"{name}: {what}" for name, what in AGENT_KINDS.items()),
    )
    _count(evaluate, "--episodes", MAX_EPISODES, 20, "episodes per agent")
    evaluate.add_argument(
        "--output", type=Path, help=_stem_help(EVALUATION_SUFFIXES, "OUTPUT.md, OUTPUT.csv, OUTPUT.json and OUTPUT.png")
    )

    leaderboard = commands.add_parser(
        "leaderboard",
        help="every env's baselines and committed models on the same seeds, ranked by the env's main metric",
    )
    leaderboard.add_argument(
        "--agents",
        type=names,
        default="random,greedy,planner,ppo,rllib,benchmarl",
        help="comma-separated columns, each once: random, greedy, planner, ppo, rllib, benchmarl (default: all)",
    )
    leaderboard.add_argument("--envs", type=names, help="comma-separated env ids (default: every registered env)")
    leaderboard.add_argument(
        "--models",
        type=Path,
        help=f"the committed models, a directory per model (default: {DEFAULT_MODELS}, if present)",
    )
    _count(leaderboard, "--episodes", MAX_EPISODES, 50, "episodes per agent")
    leaderboard.add_argument(
        "--output",
        type=Path,
        default=Path("results/leaderboard"),
        help=_stem_help(LEADERBOARD_SUFFIXES, "OUTPUT.md and OUTPUT.json (default: results/leaderboard)"),
    )
    for command in (evaluate, leaderboard):
        _count(command, "--workers", MAX_WORKERS, 1, "episodes played at once, each in its own process")
        command.add_argument("--ray", action="store_true", help="play them as Ray tasks (the distributed extra)")
        command.add_argument("--address", help="with --ray: an existing Ray cluster (default: a local Ray)")

    render = commands.add_parser("render", help="render one episode of an agent: PREFIX.gif (animated), PREFIX.png")
    render.add_argument("--env", default=DEFAULT_ENV, help=f"env id (default: {DEFAULT_ENV})")
    render.add_argument(
        "--agents", default="greedy", help=f"one agent (default: greedy): {', '.join(AGENT_KINDS)}, as evaluate takes"
    )
    render.add_argument(
        "--output",
        type=Path,
        required=True,
        metavar="PREFIX",
        help=_stem_help(RENDER_SUFFIXES, "PREFIX.gif and PREFIX.png"),
    )
    _count(render, "--every", MAX_STEPS, 1, "keep every K-th step's frame")
    render.add_argument(
        "--max-steps", type=integer(1, MAX_STEPS), help="stop after N steps (default: when the episode ends)"
    )

    train = commands.add_parser("train", help="train PPO (MaskablePPO with action masks); save model.zip")
    train.add_argument(
        "--env", required=True, help="env id, e.g. infonav/LandmarkSelection-v0 or cooperative_localization_v0"
    )
    train.add_argument(
        "--timesteps",
        type=integer(0, MAX_TIMESTEPS),
        required=True,
        help="env steps to train for (robot steps in a team); 0 with --init-from-planner: behaviour cloning alone",
    )
    train.add_argument(
        "--n-envs",
        type=integer(1, MAX_COPIES),
        help="sb3: vectorized env copies (default: the hyperparameters' n_envs); a team copy gives each robot a slot",
    )
    train.add_argument("--output", type=Path, help="output directory (default: models/ENV-NAME_seedS)")
    train.add_argument(
        "--hyperparams",
        type=Path,
        metavar="FILE",
        help="PPO hyperparameters: a YAML file of blocks keyed by env id, rl-zoo style "
        "(default: the tuned blocks shipped in the package, agents/hyperparams/ppo.yml)",
    )
    train.add_argument(
        "--vectorization",
        choices=("native", "sync", "subprocess"),
        help="sb3: native: the env's own vector env, all copies stepped at once (the default where the env has one); "
        "sync: one process, copy after copy (DummyVecEnv; the default otherwise); subprocess: one process per copy",
    )
    train.add_argument("--tensorboard", action="store_true", help="sb3: log to OUTPUT/tensorboard (needs tensorboard)")
    train.add_argument(
        "--init-from-planner",
        type=episodes_or_file,
        metavar="EPISODES|FILE",
        help="sb3: warm-start the policy by behaviour cloning of the env's planner before PPO: play EPISODES planner "
        "episodes (saved as OUTPUT/demonstrations.npz), or clone from such a FILE again",
    )
    train.add_argument(
        "--workers",
        type=integer(1, MAX_WORKERS),
        help="processes that play the planner's episodes of --init-from-planner (default: 1)",
    )
    train.add_argument(
        "--eval-episodes",
        type=integer(1, MAX_EPISODES),
        metavar="K",
        help="sb3: keep the policy best on K validation episodes (seeds from 2000000, deterministic, the env's main "
        "metric) in OUTPUT/best/, validated at the start, every --eval-every steps and at the end",
    )
    train.add_argument(
        "--eval-every",
        type=integer(1, MAX_TIMESTEPS),
        metavar="STEPS",
        help="env steps between validations of --eval-episodes (default: a twentieth of --timesteps)",
    )
    train.add_argument(
        "--stop-at",
        type=number(-math.inf, math.inf),
        metavar="METRIC",
        help="sb3: stop training once a validation's mean main metric reaches METRIC (e.g. 1.0: every validation "
        "episode a success); OUTPUT/best/ holds that policy",
    )
    train.add_argument(
        "--backend",
        choices=("sb3", "rllib", "benchmarl"),
        default="sb3",
        help="sb3: Stable-Baselines3 MaskablePPO (default); rllib: Ray RLlib PPO (the distributed extra); benchmarl: "
        "BenchMARL's --algorithm on a team env, --timesteps team steps (the marl extra)",
    )
    train.add_argument("--algorithm", help="benchmarl: mappo (default) or ippo, one policy shared by the robots")
    train.add_argument(
        "--num-env-runners",
        type=integer(0, MAX_WORKERS),
        help="rllib: env runner processes; 0 samples in the driver process (default: 1)",
    )
    train.add_argument(
        "--envs-per-runner",
        type=integer(1, MAX_COPIES),
        help="rllib: env copies per runner (default: a team env's ppo.yml n_envs over the runners, stepped at once; "
        "1 of a single-agent env)",
    )
    train.add_argument(
        "--policies",
        choices=("shared", "per_robot"),
        help="rllib, team env: one policy shared by every robot (default) or one per robot",
    )
    train.add_argument("--address", help="rllib: an existing Ray cluster (default: a local Ray)")

    dataset = commands.add_parser(
        "dataset", help="record an agent's episodes into a local Minari dataset that recreates the env (data extra)"
    )
    dataset.add_argument("--env", default=DEFAULT_ENV, help=f"env id, single-agent or team (default: {DEFAULT_ENV})")
    dataset.add_argument(
        "--agent", default="greedy", help=f"one agent (default: greedy): {', '.join(AGENT_KINDS)}, as evaluate takes"
    )
    _count(dataset, "--episodes", MAX_EPISODES, 10, "episodes, on seeds from --seed on")
    dataset.add_argument(
        "--output", type=Path, default=DEFAULT_DATASETS, help=f"datasets directory (default: {DEFAULT_DATASETS})"
    )
    dataset.add_argument("--dataset-id", help="Minari dataset id (default: infonav/ENV/AGENT-v0)")
    dataset.add_argument("--overwrite", action="store_true", help="replace a dataset of that id in --output")
    clone = commands.add_parser(
        "clone", help="behaviour cloning of a dataset of infonav dataset: a policy infonav evaluate plays as ppo:DIR"
    )
    clone.add_argument("dataset", type=Path, help="the dataset's directory, DIR/ID of infonav dataset")
    clone.add_argument(
        "--output",
        type=Path,
        help="model directory (default: models/NAME_bc_seedS, or NAME_dagger_seedS with --dagger; NAME the dataset's)",
    )
    clone.add_argument(
        "--dagger",
        type=integer(1, MAX_ROUNDS),
        metavar="ROUNDS",
        help="then ROUNDS rounds of DAgger: the latest policy drives --dagger-episodes episodes (seeds from 5000000 + "
        "--seed on) while the env's planner labels every decision, and a new policy is fitted to all labels so far; "
        "round R's policy in OUTPUT/round_R, the last one in OUTPUT, every round in OUTPUT/dagger.json",
    )
    clone.add_argument(
        "--dagger-episodes", type=integer(1, MAX_EPISODES), metavar="K", help="episodes per DAgger round (default: 10)"
    )
    clone.add_argument(
        "--workers", type=integer(1, MAX_WORKERS), help="processes that play a DAgger round's episodes (default: 1)"
    )
    clone.add_argument(
        "--eval-episodes",
        type=integer(0, MAX_EPISODES),
        metavar="K",
        help="validate each DAgger round's policy on K episodes (seeds from 2000000 + --seed, deterministic, the env's "
        "main metric; default: 10)",
    )

    benchmark = commands.add_parser("benchmark", help="speed goals as ratios against CartPole-v1, same process")
    _count(benchmark, "--rounds", MAX_ROUNDS, 5, "alternating measurement rounds")
    benchmark.add_argument(
        "--seconds", type=number(0, MAX_SECONDS), default=1.0, help="seconds per env per round (default: 1)"
    )
    benchmark.add_argument(
        "--vector-sizes",
        type=_vector_sizes,
        default=DEFAULT_VECTOR_SIZES,
        help=f"comma-separated sub-env counts N of the vector envs (default: {DEFAULT_VECTOR_SIZES_TEXT})",
    )
    benchmark.add_argument(
        "--plot", type=Path, help="also write the steps/s-against-N curves to PLOT.png (.png added unless given)"
    )

    reproduce = commands.add_parser(
        "reproduce",
        help="regenerate a figure of the paper: PNG, JSON and a summary",
        description=f"Regenerate a figure of the paper; writes FIGURE.png and FIGURE.json into --output-dir "
        f"(default: ./{DEFAULT_OUTPUT_DIR}, created if missing; existing files are overwritten).",
    )
    reproduce.add_argument("figure", choices=FIGURES, help="which figure")
    reproduce.add_argument(
        "--output-dir",
        type=Path,
        default=DEFAULT_OUTPUT_DIR,
        help=f"where to write FIGURE.png and FIGURE.json (default: ./{DEFAULT_OUTPUT_DIR}, in the working directory)",
    )
    _count(reproduce, "--seeds", MAX_SEEDS, 20, "seeds averaged from --seed on")

    replay = commands.add_parser("replay", help="replay measurement-selection policies on logged real robot data")
    replay_sources = replay.add_subparsers(dest="source", required=True)
    mrclam = replay_sources.add_parser("mrclam", help="a UTIAS MRCLAM dataset directory (Datasets 1-9)")
    mrclam.add_argument("dataset_dir", type=Path, help="directory with Barcodes.dat, RobotN_Odometry.dat, ...")
    mrclam.add_argument(
        "--policy", type=names, default="all", help="comma-separated: all, greedy, random, nearest (default: all)"
    )
    mrclam.add_argument("--seeds", type=integer(1, MAX_SEEDS), default=1, help="random-policy runs from --seed on")
    mrclam.add_argument(
        "--cooperative",
        action="store_true",
        help="one joint EKF of the team (mrclam_cooperative_localization_v0), with teammates' readings",
    )
    mrclam.add_argument(
        "--outage-robot",
        type=integer(1, MAX_ROBOT),
        help="also run the outage experiment (a cooperative replay) for this robot (subject #)",
    )
    mrclam.add_argument(
        "--outage-start-s", type=number(0, MAX_LOG_S, low_open=False), default=0.0, help="outage start [s] (default: 0)"
    )
    mrclam.add_argument("--outage-end-s", type=end_time, default=float("inf"), help="outage end [s] (default: the end)")
    mrclam.add_argument(
        "--duration-s", type=number(0, MAX_LOG_S), help="replay (or --calibrate on) only the first DURATION_S seconds"
    )
    mrclam.add_argument(
        "--output",
        type=Path,
        help=_stem_help(REPLAY_SUFFIXES, "OUTPUT.md, OUTPUT.json and, when --policy includes all, OUTPUT_nees.png"),
    )
    mrclam.add_argument(
        "--noise",
        default="shipped",
        help="the logs replayed: corrected by a calibration JSON file, by 'shipped' (fitted on Dataset 6, the "
        "default), or 'picked' (raw); the envs' noise is the dataset README's stds either way",
    )
    mrclam.add_argument(
        "--compare-noise", help="also run every experiment with this noise model (as --noise) and report both"
    )
    mrclam.add_argument(
        "--calibrate",
        type=Path,
        metavar="OUTPUT.json",
        help="fit the noise model to DATASET_DIR's ground truth, write OUTPUT.json and OUTPUT.png, replay nothing "
        "(the options of a replay are refused with it)",
    )
    for command in (evaluate, render, train, dataset):
        command.add_argument(
            "--config", type=_config_pair, action="append", default=[], metavar="KEY=VALUE", help="env config override"
        )
    for command in (demo, evaluate, leaderboard, render, train, dataset, clone, benchmark, reproduce, mrclam):
        command.add_argument("--seed", type=seed, default=0, help="first seed, from 0 to 2**32 - 1 (default: 0)")
        command.add_argument("--json", action="store_true", help="print one JSON object on stdout instead of tables")
    return parser


def _plot_file(plot: Path | None) -> Path | None:
    """The PNG file ``--plot PLOT`` writes (``PLOT_SUFFIX`` added unless given), checked before the work; None
    without ``--plot``."""
    return plot and output_file(check_output_stem(plot, (PLOT_SUFFIX,), "--plot"), PLOT_SUFFIX)


def _demo(args, command: str) -> dict:
    from infonav_gym.experiments.demo import demo_table, figure_information_field, run_demo
    from infonav_gym.rendering import save_figure

    plot = _plot_file(args.plot)
    result = run_demo(steps=args.steps, seed=args.seed, progress=not args.json)
    if plot:
        result["plot"] = str(save_figure(figure_information_field(args.seed), plot, dpi=120, bbox_inches="tight"))
    return _show(args, result, lambda: [demo_table(result)] + ([f"\nwrote {result['plot']}"] if plot else []))


def _show(args, result: dict, lines, write=None, where: str = "") -> dict:
    """Run ``write()`` (it returns the paths written) into ``result["files"]``, print the ``lines()`` unless --json,
    then raise a failed write as ``OutputWriteError`` carrying ``result`` (the table is printed all the same)."""
    failure = None
    try:
        if write:
            result["files"] = [str(path) for path in write()]
    except OSError as error:
        failure = write_failure(where, error)
    for line in [] if args.json else lines():
        print(line)
    if failure:
        raise OutputWriteError(failure, result)
    return result


def _how_played(args) -> dict:
    """The keywords of ``evaluate`` and ``leaderboard`` saying how episodes are played, once --address is checked."""
    if args.address and not args.ray:
        raise ValueError("--address is the Ray cluster of --ray; add --ray or drop --address")
    return {"progress": not args.json, "workers": args.workers, "use_ray": args.ray, "address": args.address}


def _leaderboard(args, command: str) -> dict:
    """Play the leaderboard; write OUTPUT.md and OUTPUT.json (the finished rows on Ctrl-C); print it unless --json."""
    from infonav_gym.experiments.leaderboard import heading, leaderboard, markdown_tables, write_leaderboard

    stem = check_output_stem(args.output, LEADERBOARD_SUFFIXES, "--output")
    how = _how_played(args)
    if args.models and not args.models.is_dir():
        raise ValueError(f"--models {args.models}: not a directory (the committed models, one directory each)")
    models = args.models or (DEFAULT_MODELS if DEFAULT_MODELS.is_dir() else None)
    interruption = None
    try:
        results = leaderboard(args.envs, args.agents, models, args.episodes, args.seed, **how)
    except Interrupted as error:  # the finished rows are written and printed as a whole leaderboard's
        results, interruption = error.result, error
        if not results["rows"]:
            raise Interrupted("interrupted before a row finished: nothing to write", results) from None

    def lines():
        return [heading(results), markdown_tables(results)]

    _show(args, results, lines, lambda: write_leaderboard(results, stem, command), f"--output {stem}")
    if interruption:
        raise Interrupted(f"{interruption}; wrote {', '.join(results['files'])}", results)
    return results


def _evaluate(args, command: str) -> dict:
    from infonav_gym.experiments.evaluation import evaluate
    from infonav_gym.experiments.evaluation_files import config_line, heading, markdown_table, write_results

    stem = check_output_stem(args.output, EVALUATION_SUFFIXES, "--output") if args.output else None
    how = _how_played(args)
    try:
        results = evaluate(args.env, args.agents, args.episodes, args.seed, dict(args.config), **how)
        interruption = None
    except Interrupted as error:  # the episodes finished so far are written and printed as a whole evaluation's
        results, interruption = error.result, error
        if not results["agents"]:
            raise Interrupted("interrupted before every agent finished a seed: nothing to write", results) from None

    def lines():
        return [heading(results), config_line(results), markdown_table(results)]

    _show(args, results, lines, stem and (lambda: write_results(results, stem, command)), f"--output {stem}")
    if interruption:
        kept = "the tables above hold them" if not args.json else "the JSON on stdout holds them"
        kept = f"wrote {', '.join(results['files'])}" if stem else kept
        raise Interrupted(f"{interruption}; {kept}", results)
    return results


def _render(args, command: str) -> dict:
    """Render one episode into ``args.output`` .gif and .png; print what was written unless --json."""
    from infonav_gym.experiments.render_episode import STRIP_DPI, figure_strip, render_episode, write_gif
    from infonav_gym.rendering import require_extra, save_figure

    if "," in args.agents:
        raise ValueError(f"--agents takes one agent to render, got {args.agents!r}")
    stem = check_output_stem(args.output, RENDER_SUFFIXES, "--output")
    require_extra("PIL", "infonav render's GIF")  # before the episode, not after it
    require_extra("matplotlib", "infonav render's PNG")
    episode = render_episode(
        args.env, args.agents, args.seed, dict(args.config), args.every, args.max_steps, progress=not args.json
    )
    steps = episode.steps[-1]
    result = {"env_id": args.env, "agent": args.agents, "seed": args.seed, "steps": steps, "frames": len(episode.steps)}
    title = f"{args.env}, {args.agents}, seed {args.seed}"

    def write():
        stem.parent.mkdir(parents=True, exist_ok=True)
        gif, png = (output_file(stem, suffix) for suffix in RENDER_SUFFIXES)
        return [write_gif(episode, gif), save_figure(figure_strip(episode, title), png, dpi=STRIP_DPI)]

    def lines():
        yield f"{title}: {steps} steps, {len(episode.steps)} frames (every {args.every})"
        yield from (f"wrote {path} ({Path(path).stat().st_size / 1e6:.2f} MB)" for path in result.get("files", []))

    return _show(args, result, lines, write, f"--output {stem}")


def _curve_references(env_id: str, env_kwargs: dict) -> dict | None:
    """The greedy and planner means of the env's main metric in ``LEADERBOARD_JSON`` for this env and config (the
    lines of the learning curve); None without that file or its row."""
    if not LEADERBOARD_JSON.is_file():
        return None
    for row in json.loads(LEADERBOARD_JSON.read_text())["rows"]:
        if row["env_id"] == env_id and row["env_kwargs"] == env_kwargs:
            cells = row["cells"]
            return {agent: cells[agent]["summary"]["mean"] for agent in CURVE_REFERENCES if cells.get(agent)}
    return None


TRAIN_BACKEND_OPTIONS = {  # train's option: (the one backend that reads it, what it does there)
    "init_from_planner": ("sb3", "warm-starts SB3's MaskablePPO"),
    "eval_episodes": ("sb3", "keeps the best SB3 policy"),
    "stop_at": ("sb3", "stops SB3's training at a validation mean"),
    "n_envs": ("sb3", "sets SB3's env copies (rllib: --envs-per-runner)"),
    "vectorization": ("sb3", "picks how SB3 steps its env copies"),
    "tensorboard": ("sb3", "logs SB3's training"),
    "num_env_runners": ("rllib", "sets RLlib's env runner processes"),
    "envs_per_runner": ("rllib", "sets the env copies of each RLlib env runner"),
    "policies": ("rllib", "lays out RLlib's policies in a team env"),
    "address": ("rllib", "names the Ray cluster RLlib trains on"),
    "algorithm": ("benchmarl", "picks BenchMARL's algorithm"),
}
TRAIN_OPTION_NEEDS = {  # train's option: (the option it needs, what that one gives)
    "eval_every": ("eval_episodes", "how many validation episodes"),
    "stop_at": ("eval_episodes", "the validation episodes whose mean it compares"),
    "workers": ("init_from_planner", "the planner episodes the workers play"),
}


def _flag(dest: str) -> str:
    return "--" + dest.replace("_", "-")


def _check_train_options(args) -> None:
    """``ValueError`` naming an option the chosen backend ignores, or one given without the option it needs."""
    given = {dest for dest, value in vars(args).items() if value is not None and value is not False}
    for dest, (backend, does) in TRAIN_BACKEND_OPTIONS.items():
        if dest in given and backend != args.backend:
            raise ValueError(f"{_flag(dest)} {does}: use it with --backend {backend} ({args.backend} ignores it)")
    for dest, (needed, gives) in TRAIN_OPTION_NEEDS.items():
        if dest in given and needed not in given:
            raise ValueError(f"{_flag(dest)} needs {_flag(needed)} ({gives})")
    if args.workers is not None and isinstance(args.init_from_planner, Path):
        raise ValueError("--workers play the planner's episodes of --init-from-planner EPISODES; a FILE plays none")


def _train(args, command: str) -> dict:
    """Train PPO on ``args.env`` with SB3 or RLlib, or BenchMARL's MAPPO / IPPO; print where the model went unless
    --json."""
    rllib, benchmarl = args.backend == "rllib", args.backend == "benchmarl"
    _check_train_options(args)
    if rllib:
        from agents.ray_support import import_ray

        import_ray(args.address)  # a missing extra or a wrong address: a one-line error before the slow imports below
        from agents.rllib_train import train_rllib
    if benchmarl:
        from agents.benchmarl_agent import import_benchmarl_training

        train_benchmarl = import_benchmarl_training().train_benchmarl  # a missing extra: a one-line error
    try:
        from agents.ppo import load_hyperparameters, train
    except ImportError as error:
        raise ValueError(f"training needs the rl extra (pip install 'infonav-gym[rl]'): {error}") from None
    planner_workers = args.workers or 1
    if isinstance(args.init_from_planner, int):  # the planner's episodes: as many workers as episodes at most
        planner_workers = checked_workers(planner_workers, args.init_from_planner, 0, "the planner's episodes")
    name = f"{args.env.rsplit('/', 1)[-1]}{'' if args.backend == 'sb3' else '_' + args.backend}_seed{args.seed}"
    output = check_output_dir(args.output or Path("models") / name, "--output")
    env_kwargs = dict(args.config)
    shared = {"seed": args.seed, "env_kwargs": env_kwargs, "progress": not args.json}  # every backend takes them
    shared["curve_references"] = _curve_references(args.env, env_kwargs)
    if rllib:
        options = {key: getattr(args, key) for key in ("num_env_runners", "envs_per_runner", "policies", "address")}
        record = train_rllib(
            args.env,
            args.timesteps,
            output,
            **shared,
            hyperparameters=load_hyperparameters(args.env, args.hyperparams),
            **{key: value for key, value in options.items() if value is not None},  # else train_rllib's defaults
        )
        copies = f"{record['num_env_runners']} env runners x {record['envs_per_runner']} envs"
        written, agent = f"checkpoint: {record['checkpoint']}", f"rllib:{output}"
    elif benchmarl:
        record = train_benchmarl(
            args.env,
            args.timesteps,
            output,
            args.algorithm or "mappo",
            **shared,
            hyperparameters=load_hyperparameters(args.env, args.hyperparams),
        )
        saved, copies = record["actor"]["file"], f"{record['n_envs']} envs"
        written, agent = f"actor: {saved}", f"benchmarl:{output}"
    else:
        model_path = train(
            args.env,
            args.timesteps,
            **shared,
            n_envs=args.n_envs,
            output_dir=output,
            hyperparameters=load_hyperparameters(args.env, args.hyperparams) if args.hyperparams else None,
            tensorboard=args.tensorboard,
            vectorization=args.vectorization,
            init_from_planner=args.init_from_planner,
            planner_workers=planner_workers,
            validation_episodes=args.eval_episodes or 0,
            validation_every=args.eval_every,
            validation_stop_at=args.stop_at,
        )
        record, saved = json.loads((model_path.parent / "train.json").read_text()), model_path
        copies = f"{record['n_envs']} envs, {record['vectorization']}"
        written, agent = f"model: {model_path}", f"ppo:{model_path}"
    if record.get("interrupted"):
        message = f"interrupted after {record['timesteps']} of {args.timesteps} env steps; saved {saved}"
        raise Interrupted(f"{message} and train.json", record)
    if not args.json:
        print(
            f"trained {record['algorithm']} on {args.env} ({copies}) for {record['timesteps']} env steps in "
            f"{record['seconds']:.1f} s ({record['fps']:.0f} steps/s); {written}"
        )
        if record.get("warm_start"):
            start = record["warm_start"]
            print(
                f"warm start: cloned {start['rows']} planner decisions ({start['demonstrations']}), "
                f"{start['agreement']:.0%} agreement"
            )
        if record.get("validation"):
            kept = record["validation"]
            print(
                f"best on {kept['episodes']} validation episodes: {kept['best_metric']:.4g} after "
                f"{kept['best_steps']} env steps; model: {kept['best']}"
            )
            if kept.get("stopped_at") is not None:
                print(f"stopped: a validation reached --stop-at {kept['stop_at']:g} at {kept['stopped_at']} env steps")
        print(f"learning curve: {record['curve']}")
        config_flags = "".join(f" --config {shlex.quote(f'{key}={json.dumps(value)}')}" for key, value in args.config)
        print(f"evaluate it: infonav evaluate --env {args.env}{config_flags} --agents random,greedy,{agent}")
    return record


def _dataset(args, command: str) -> dict:
    """Record ``args.agent`` into a Minari dataset; print what was written unless --json."""
    from infonav_gym.experiments.dataset import record_dataset

    result = record_dataset(
        args.env,
        args.agent,
        args.episodes,
        args.output,
        args.dataset_id,
        args.seed,
        dict(args.config),
        args.overwrite,
        progress=not args.json,
    )
    where, dataset_id = result["path"], result["dataset_id"]
    lines = [
        f"recorded {result['episodes']} episodes ({result['steps']} steps) of {args.agent} on {args.env}: {where}",
        f"load it: MINARI_DATASETS_PATH={args.output} python -c \"import minari; minari.load_dataset('{dataset_id}')\"",
        f"clone it: infonav clone {where}",
    ]
    return _show(args, result, lambda: lines)


def _clone(args, command: str) -> dict:
    """Behaviour cloning of ``args.dataset``; print where the model went unless --json."""
    from infonav_gym.experiments.dataset import clone_dataset

    flags = {"--dagger-episodes": "dagger_episodes", "--workers": "workers", "--eval-episodes": "validation_episodes"}
    values = {flag: getattr(args, flag[2:].replace("-", "_")) for flag in flags}
    given = [flag for flag, value in values.items() if value is not None]
    if given and args.dagger is None:
        raise ValueError(f"{', '.join(given)} only go with --dagger ROUNDS")
    name = f"{args.dataset.resolve().name.rsplit('-v', 1)[0]}_{'dagger' if args.dagger else 'bc'}_seed{args.seed}"
    output = check_output_dir(args.output or Path("models") / name, "--output")
    options = {flags[flag]: values[flag] for flag in given}  # the others: clone_dataset's defaults
    model_path = clone_dataset(args.dataset, output, args.seed, not args.json, args.dagger or 0, **options)
    record = json.loads((model_path.parent / "train.json").read_text())
    start = record["warm_start"]
    lines = [
        f"cloned {start['rows']} decisions of {start['demonstrations']} ({start['agreement']:.0%} agreement); "
        f"model: {model_path}",
    ]
    if args.dagger:  # the rounds' lines instead: the last round's demonstrations are more than the recorded ones
        from infonav_gym.experiments.dagger import RECORD_FILE

        record["dagger"] = json.loads((output / RECORD_FILE).read_text())
        lines = [_dagger_round(done) for done in record["dagger"]["done"]]
        if "best_round" in record["dagger"]:
            best = record["dagger"]["done"][record["dagger"]["best_round"]]
            lines.append(f"best on validation: round {best['round']}, ppo:{best['model']}")
    config_flags = "".join(
        f"--config {shlex.quote(f'{key}={json.dumps(value)}')} " for key, value in record["env_kwargs"].items()
    )
    lines.append(f"evaluate it: infonav evaluate --env {record['env_id']} {config_flags}--agents greedy,ppo:{output}")
    return _show(args, record, lambda: lines)


def _dagger_round(done: dict) -> str:
    """One line of a DAgger round's record (``dagger.json``)."""
    line = f"round {done['round']}: fitted {done['rows']} decisions ({done['agreement_fitted']:.0%} agreement)"
    if done["validation_mean"] is not None:
        line += f", validation mean {done['validation_mean']:.3f}"
    if "agreement_on_own_states" in done:
        line += f"; {done['agreement_on_own_states']:.0%} agreement on the states it then drove to"
    return line + f"; {done['model']}"


def _benchmark(args, command: str) -> dict:
    from infonav_gym.experiments.benchmark import lower_is_better, plot_throughput, run_benchmark
    from infonav_gym.rendering import require_extra

    plot = _plot_file(args.plot)
    if plot:
        require_extra("matplotlib", "benchmark --plot")  # before the run, not after it
    result = run_benchmark(
        rounds=args.rounds,
        seconds_per_round=args.seconds,
        seed=args.seed,
        progress=not args.json,
        vector_sizes=args.vector_sizes,
    )

    def lines():
        goals, met = result["goals"], result["goals_met"]
        for name, value in result["figures"].items():
            goal = ""
            if name in goals:
                relation = "<=" if lower_is_better(name) else ">="
                goal = f"  (goal {relation} {goals[name]}: {'met' if met[name] else 'NOT met'})"
            yield f"{name:40s} {value:12.3f}{goal}"
        yield from result["notes"]
        yield from (f"wrote {path}" for path in result.get("files", []))

    return _show(args, result, lines, plot and (lambda: [plot_throughput(result["figures"], plot)]), f"--plot {plot}")


def _reproduce(args, command: str) -> dict:
    """``reproduce_figure`` of the figure; print its table unless --json, even when writing the files fails."""
    try:
        result = reproduce_figure(args.figure, args.output_dir, args.seed, args.seeds, not args.json, command)
    except OutputWriteError as error:
        kept = error.result
        _show(args, kept, lambda: [printed_table(args.figure, kept)])
        raise
    return _show(args, result, lambda: [printed_table(args.figure, result)])


def _check_noise(value: str) -> None:
    """``--noise`` / ``--compare-noise``: 'picked', 'shipped', or a calibration file that loads (its errors)."""
    from infonav_gym.datasets.noise_model import load_noise_model

    if value not in ("picked", "shipped"):
        load_noise_model(value)


def _load_mrclam(directory):
    """Load an MRCLAM directory; print its warnings; missing paths become ``ValueError``."""
    import warnings

    from infonav_gym.datasets import mrclam

    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            dataset = mrclam.load(directory)
    except OSError as error:  # a missing directory or file, a file where the directory belongs
        raise ValueError(str(error)) from None
    for warning in caught:
        print(f"infonav replay: warning: {warning.message}", file=sys.stderr)
    return dataset


def _replay_options_given(args) -> list[str]:
    """The options of ``replay mrclam`` that ``args`` sets to other than their defaults, e.g. ``["--policy"]``."""
    defaults = vars(build_parser().parse_args(["replay", "mrclam", str(args.dataset_dir)]))
    shared = ("command", "source", "dataset_dir", "calibrate", "json")
    return [_flag(key) for key, value in vars(args).items() if key not in shared and value != defaults[key]]


def _calibrate(args, command: str) -> dict:
    """Fit the noise model of ``args.dataset_dir``; write the JSON and the residual plot."""
    from infonav_gym.experiments.replay.calibration import calibrate
    from infonav_gym.experiments.replay.plots import plot_calibration

    if ignored := [option for option in _replay_options_given(args) if option != "--duration-s"]:
        them = "it" if len(ignored) == 1 else "them"
        raise ValueError(f"--calibrate only fits the noise model: {', '.join(ignored)} would be ignored; drop {them}")
    stem = check_output_stem(args.calibrate, CALIBRATION_SUFFIXES, "--calibrate")
    dataset = _load_mrclam(args.dataset_dir)
    if args.duration_s is not None:  # fit on the log's first seconds only: the rest stays unseen
        dataset = dataset.within(0.0, args.duration_s)
    model, errors = calibrate(dataset, command=command, progress=not args.json)
    result = model.to_json()

    def write():
        stem.parent.mkdir(parents=True, exist_ok=True)
        path_json, png = (output_file(stem, suffix) for suffix in CALIBRATION_SUFFIXES)
        return [model.save(path_json), plot_calibration(model, errors, png)]

    return _show(args, result, lambda: [calibration_table(model)], write, f"--calibrate {args.calibrate}")


def calibration_table(model) -> str:
    """The fitted parameters as Markdown, one column per robot and pooled."""
    import dataclasses

    from infonav_gym.experiments.replay.tables import table_lines

    columns = {f"robot {subject}": noise for subject, noise in sorted(model.robots.items())} | {"pooled": model.pooled}
    rows = [
        [field.name, *(f"{getattr(noise, field.name):.4g}" for noise in columns.values())]
        for field in dataclasses.fields(model.pooled)
    ]
    return "\n".join(table_lines(["parameter", *columns], rows))


def _replay(args, command: str) -> dict:
    """Load an MRCLAM directory, replay the policies asked for; print the table unless --json."""
    from infonav_gym.experiments.replay import (
        ReplayConfig,
        check_experiments,
        markdown_table,
        run_experiments,
        write_results,
    )
    from infonav_gym.experiments.replay.comparison import compare, comparison_markdown

    if args.calibrate:
        return _calibrate(args, command)
    check_experiments(args.policy, args.seeds)  # before the dataset loads
    ReplayConfig(outage_start_s=args.outage_start_s, outage_end_s=args.outage_end_s)  # its outage span check, too
    outage_span = [name for name in ("--outage-start-s", "--outage-end-s") if name in _replay_options_given(args)]
    if outage_span and args.outage_robot is None:
        raise ValueError(f"{' and '.join(outage_span)} set the outage of --outage-robot ROBOT: add it, or drop them")
    stem = check_output_stem(args.output, REPLAY_SUFFIXES, "--output") if args.output else None
    for noise in filter(None, (args.noise, args.compare_noise)):
        _check_noise(noise)  # a calibration file that does not load: before any replay
    dataset = _load_mrclam(args.dataset_dir)
    if not dataset.has_groundtruth:
        missing = [robot for robot in dataset.robots if robot not in dataset.groundtruth]
        print(f"infonav replay: no ground truth for robot(s) {missing}: they are not replayed", file=sys.stderr)
    if args.outage_robot is not None and args.outage_robot not in dataset.robots:
        raise ValueError(f"outage robot {args.outage_robot} is not one of the robots {list(dataset.robots)}")
    outage = (args.outage_robot, args.outage_start_s, args.outage_end_s) if args.outage_robot is not None else None

    def sweep(noise):
        return run_experiments(
            args.dataset_dir,
            args.policy,
            n_seeds=args.seeds,
            seed=args.seed,
            outage=outage,
            config=ReplayConfig(cooperative=args.cooperative, noise=noise, duration_s=args.duration_s),
            progress=not args.json,
        )

    result = sweep(args.noise)
    if args.compare_noise:
        before = sweep(args.compare_noise)
        result["comparison"] = compare(result, before)
        result["compared_rows"] = before["rows"]

    def lines():
        yield markdown_table(result)
        if args.compare_noise:
            yield "\n" + comparison_markdown(result["comparison"])

    return _show(args, result, lines, stem and (lambda: write_results(result, stem, command)), f"--output {stem}")


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if "" not in sys.path and os.getcwd() not in sys.path:  # as `python -m`: --env MODULE:ID finds ./MODULE.py
        sys.path.insert(0, os.getcwd())
    parser = build_parser()
    args = parser.parse_args(argv)
    run = {"demo": _demo, "evaluate": _evaluate, "render": _render, "train": _train, "benchmark": _benchmark}
    run |= {"reproduce": _reproduce, "replay": _replay, "leaderboard": _leaderboard, "dataset": _dataset}
    run |= {"clone": _clone}
    try:
        result = run[args.command](args, "infonav " + shlex.join(argv))
    except (OutputWriteError, Interrupted) as kept:  # the work kept was printed; its JSON still is with --json
        if args.json:
            print(json.dumps(kept.result))
        interrupted = isinstance(kept, Interrupted)
        parser.exit(130 if interrupted else 2, f"infonav {args.command}: {'' if interrupted else 'error: '}{kept}\n")
    except INTERRUPTIONS as error:
        if not pressed_ctrl_c(error):
            raise
        parser.exit(130, f"infonav {args.command}: interrupted\n")
    except (ValueError, ImportError, OSError) as error:  # OSError: a file not read or written, e.g. demo --plot
        parser.exit(2, f"infonav {args.command}: error: {error}\n")
    if args.json:
        print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
