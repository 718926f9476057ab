"""Sphinx extension: one page per registered env, written from the registry and the env itself at each build.

For every env in ``infonav_gym.registry.registered_envs()`` it writes ``docs/generated/envs/<stem>.md``:
the env class's docstring, the spaces of a made env, its config keys with their defaults and the allowed values
its own checks state (``infonav_gym.config.stated_requirements``), its episode metrics and traits, its frame and
episode GIF from ``docs/frames`` (``scripts/render_frames.py``) and every committed evaluation of it in
``results/``. A new env gets its page by being registered; nothing here names one.
"""

from __future__ import annotations

import dataclasses
import inspect
import os
import re
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")

import numpy as np
from page_writing import DOCS, code, markdown_table, write_page

import infonav_gym
from infonav_gym.config import stated_requirements
from infonav_gym.envs.traits import episode_metrics_of, traits_of
from infonav_gym.experiments.render_episode import frame_stem
from infonav_gym.registry import PARALLEL, EnvEntry, make_env, registered_envs

FRAMES = DOCS / "frames"
PACKAGE = Path(infonav_gym.__file__).resolve().parent
COMMENTED_KEY = re.compile(  # a default's comment, ``"key": 1.0,  # ...`` (not an interval's, ``"key": Interval(...``)
    r'^\s*"(\w+)": (?!Interval\()[^#\n]+,\s*#\s*(.+)$', flags=re.M
)
RESULTS = DOCS.parent / "results"


def shown(value) -> str:
    """``repr(value)``, a set's items sorted: the same text at every build (string hashes vary by process)."""
    if isinstance(value, (set, frozenset)):
        return "{" + ", ".join(sorted(map(repr, value))) + "}"
    return repr(value)


def spaces_of(env, parallel: bool) -> dict[str, tuple]:
    """``{who: (observation space, action space)}``: the env's, or each robot's of a team env."""
    if not parallel:
        return {"the agent": (env.observation_space, env.action_space)}
    return {agent: (env.observation_space(agent), env.action_space(agent)) for agent in env.possible_agents}


def space_row(who: str, kind: str, space) -> list[str]:
    """A row of the spaces table: whose, which, the space's class, shape, dtype and bounds."""
    low, high = getattr(space, "low", None), getattr(space, "high", None)
    bounds = f"[{np.min(low):g}, {np.max(high):g}]" if low is not None else f"{{0, ..., {space.n - 1}}}"
    dtype = getattr(space, "dtype", None)
    return [who, kind, code(type(space).__name__), code(space.shape), code(dtype), bounds]


def spaces_section(env, parallel: bool) -> list[str]:
    """The spaces table (robots with equal spaces in one row) and the spaces' full ``repr``."""
    groups: dict[str, tuple[tuple, list[str]]] = {}  # the spaces' reprs: (the spaces, who has them)
    for who, pair in spaces_of(env, parallel).items():
        groups.setdefault(f"observation_space = {pair[0]!r}\naction_space = {pair[1]!r}", (pair, []))[1].append(who)
    rows, reprs = [], []
    for text, ((observation, action), names) in groups.items():
        who = ", ".join(names)
        rows += [space_row(who, "observation", observation), space_row(who, "action", action)]
        reprs += [f"# {who}", text]
    header = ["who", "space", "class", "shape", "dtype", "bounds (lowest, highest)"]
    return [
        "## Spaces",
        "",
        *markdown_table(header, rows),
        "",
        "The spaces of a made env, as Python prints them:",
        "",
        "```text",
        *reprs,
        "```",
    ]


def defining_files(env_class: type) -> list[Path]:
    """The source files where ``env_class``'s config defaults are written, nearest first: those of its classes,
    then those of the functions and dicts their ``default_config`` methods name (``shared_config``,
    ``**SCENE_CONFIG``)."""
    scenario = scenario_of(env_class)
    owners = [*env_class.__mro__[1:], *(scenario.__mro__ if scenario else ())]
    classes = [env_class] + [cls for cls in owners if "default_config" in vars(cls)]
    named = {}
    for function in (vars(cls)["default_config"].__func__ for cls in classes if "default_config" in vars(cls)):
        named.update(
            {name: function.__globals__[name] for name in function.__code__.co_names if name in function.__globals__}
        )
    sources = list(classes)
    sources += [value for value in named.values() if inspect.isfunction(value)]
    files = [Path(inspect.getsourcefile(source)) for source in sources]
    for name, value in named.items():  # a dict of defaults: the module that assigns it
        if isinstance(value, dict):
            files += [path for path in PACKAGE.rglob("*.py") if re.search(rf"^{name} = {{", path.read_text(), re.M)]
    return files


def scenario_of(env_class: type) -> type | None:
    """The scenario class (``infonav_gym.envs.protocol.EnvScenario``) an env's view or vector class runs, if any."""
    vector = getattr(env_class, "vector_env", env_class)
    return getattr(vector, "scenario_class", None)


def reward_section(entry: EnvEntry) -> list[str]:
    """Where the env's reward is computed: its scenario's ``reward`` function, with its file and docstring."""
    scenario = scenario_of(entry.load_vector() if entry.vector_entry_point else entry.load())
    if scenario is None:
        return []
    path = Path(inspect.getsourcefile(scenario.reward)).relative_to(PACKAGE.parent)
    doc = inspect.getdoc(scenario.reward) or ""
    return ["## Reward function", "", f"`{scenario.__name__}.reward` in `{path.as_posix()}`: {doc}"]


def key_comments(env_class: type) -> dict[str, str]:
    """The comment beside each config key where its default is written (``"time_step_s": 0.5,  # [s]``), from the
    nearest of ``defining_files``; keys without one are left out."""
    comments: dict[str, str] = {}
    for path in defining_files(env_class):
        for key, comment in COMMENTED_KEY.findall(path.read_text()):
            comments.setdefault(key, comment)
    return comments


def config_section(entry: EnvEntry, requirements: dict[str, list[str]]) -> list[str]:
    """Every key of ``default_config()`` with its default, the allowed values its checks stated and its comment."""
    env_class = entry.load() if entry.vector_entry_point is None else entry.load_vector()  # the one that defines it
    comments = key_comments(env_class)
    rows = [
        [code(key), code(repr(default)), " and ".join(requirements.get(key, [])), comments.get(key, "")]
        for key, default in env_class.default_config().items()
    ]
    make = "make_env" if entry.api == PARALLEL else "gym.make"
    return [
        "## Config",
        "",
        f"`{make}({entry.id!r}, **config)` overrides these keys of `default_config()`; an unknown key or a value "
        "outside its range raises `ValueError` naming it. The allowed values are those the env's own checks state "
        "when it is made with the defaults (units after the interval); the last column is the comment beside the "
        "default in the source.",
        "",
        *markdown_table(["key", "default", "allowed values", "what it is [unit]"], rows),
    ]


def metrics_section(env) -> list[str]:
    """The episode metrics ``infonav evaluate`` reports, and the traits the env declares."""
    metrics = [
        [code(metric.name), metric.title, "rate (Wilson 95% interval)" if metric.proportion else "mean (Student t 95%)"]
        for metric in episode_metrics_of(env)
    ]
    traits = traits_of(env)
    trait_rows = [[code(field.name), code(shown(getattr(traits, field.name)))] for field in dataclasses.fields(traits)]
    return [
        "## Episode metrics",
        "",
        "What `infonav evaluate` reports for this env (`episode_metrics`):",
        "",
        *markdown_table(["name", "column", "summary"], metrics),
        "",
        "## Traits",
        "",
        "What the env promises code outside it (`traits`, see `infonav_gym.envs.traits.EnvTraits`):",
        "",
        *markdown_table(["trait", "value"], trait_rows),
    ]


def pictures_section(env_id: str) -> list[str]:
    """The env's frame and episode GIF from ``docs/frames``, or how to make them."""
    stem = frame_stem(env_id)
    pictures = [(FRAMES / f"{stem}{suffix}", what) for suffix, what in ((".png", "a frame"), (".gif", "an episode"))]
    found = [f"![{env_id}: {what}](../../frames/{path.name})\n" for path, what in pictures if path.is_file()]
    how = f"`python scripts/render_frames.py --env {env_id}` renders them"
    if not found:
        return ["## Rendering", "", f"No frame of this env in `docs/frames` yet: {how}."]
    return [
        "## Rendering",
        "",
        f'`render_mode="rgb_array"` under the greedy-entropy agent from `reset(seed=0)` ({how}):',
        "",
        *found,
    ]


def evaluations_of(env_id: str) -> list[Path]:
    """The committed ``infonav evaluate`` tables of ``env_id`` in ``results/`` (their first line names it)."""
    return [path for path in sorted(RESULTS.glob("*.md")) if path.read_text().startswith(f"# {env_id},")]


def results_section(env_id: str) -> list[str]:
    """Every committed evaluation of the env, included as it is in ``results/``."""
    lines = ["## Baselines", ""]
    evaluations = evaluations_of(env_id)
    if not evaluations:
        return [*lines, "No committed evaluation of this env in `results/` yet."]
    for path in evaluations:
        include = ["```{include} ../../../results/" + path.name, ":heading-offset: 2", "```"]
        lines += [f"From `results/{path.name}`:", "", *include, ""]
    return lines


def api_name(entry: EnvEntry) -> str:
    """The env's API as people name it."""
    return "PettingZoo parallel" if entry.api == PARALLEL else "Gymnasium"


def env_page(entry: EnvEntry) -> list[str]:
    """The Markdown page of one registered env."""
    with stated_requirements() as requirements:
        env = make_env(entry.id)
    try:
        parallel = entry.api == PARALLEL
        vector = entry.vector_entry_point
        made = f"`infonav_gym.make_env({entry.id!r})`" + ("" if parallel else f" or `gym.make({entry.id!r})`")
        if vector is not None:
            made += f"; its native vector env: `infonav_gym.make_vector_env({entry.id!r}, num_envs=N)` ({code(vector)})"
        lines = [
            f"# {entry.id}",
            "",
            f"API: {api_name(entry)}; entry point {code(entry.entry_point)}. Made by {made}.",
            "",
            inspect.getdoc(entry.load()) or "(no docstring)",
            "",
            *spaces_section(env, parallel),
            "",
            *reward_section(entry),
            "",
            *config_section(entry, requirements),
            "",
            *metrics_section(env),
            "",
            *pictures_section(entry.id),
            "",
            *results_section(entry.id),
        ]
    finally:
        env.close()
    return lines


def write_env_pages(app=None) -> list[Path]:
    """Write the page of every registered env and ``envs/index.md`` listing them."""
    entries = registered_envs()
    stems = [frame_stem(entry.id) for entry in entries]
    pages = [write_page(f"envs/{stem}", env_page(entry)) for stem, entry in zip(stems, entries)]
    rows = [
        [f"[{code(entry.id)}]({stem}.md)", api_name(entry), inspect.getdoc(entry.load()).partition("\n")[0]]
        for stem, entry in zip(stems, entries)
    ]
    index = [
        "# Environments",
        "",
        "One page per registered env (`infonav_gym.registry.registered_envs()`), written from the registry and the "
        "env itself at each build.",
        "",
        *markdown_table(["env", "API", "what happens"], rows),
        "",
        "```{toctree}",
        ":maxdepth: 1",
        "",
        *stems,
        "```",
    ]
    write_page("envs/index", index)
    for stale in set(pages[0].parent.glob("*.md")) - {*pages, pages[0].parent / "index.md"}:
        stale.unlink()  # an env no longer registered
    return pages


def setup(app):
    app.connect("builder-inited", write_env_pages)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
