"""Sphinx extension: the API reference page, autodoc of every public name, written at each build.

The public names are each public module's ``__all__`` (or, without one, what it defines whose name has no leading
underscore), listed one directive per name: autodoc fetches each through the module, so the lazily imported
exports of ``infonav_gym.envs``, ``world``, ``sensors`` and ``estimation`` appear as well.
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re

from page_writing import write_page

import infonav_gym.multi

PUBLIC_MODULES = {  # section title: the modules whose public names it documents
    "Registry": ["infonav_gym", "infonav_gym.registry"],
    "Information measures": ["infonav_gym.information"],
    "Config checks": ["infonav_gym.config"],
    "Single-agent environments": ["infonav_gym.envs", "infonav_gym.envs.traits", "infonav_gym.envs.metrics"],
    "Team environments (PettingZoo)": [  # the versioned entry modules, cooperative_localization_v0 and the like
        f"infonav_gym.multi.{module.name}"
        for module in pkgutil.iter_modules(infonav_gym.multi.__path__)
        if re.fullmatch(r".+_v\d+", module.name)
    ],
    "Estimation": ["infonav_gym.estimation"],
    "World and scenarios": ["infonav_gym.world"],
    "Sensors": ["infonav_gym.sensors"],
    "Registration": ["infonav_gym.registration"],
    "Datasets": ["infonav_gym.datasets"],
    "Agents": ["agents"],
}


def public_names(module) -> list[str]:
    """``module.__all__``, or the names ``module`` defines itself without a leading underscore."""
    exported = getattr(module, "__all__", None)
    if exported is not None:
        return list(exported)
    return [
        name
        for name, value in vars(module).items()
        if not name.startswith("_") and getattr(value, "__module__", None) == module.__name__
    ]


def directive(module_name: str, name: str) -> list[str]:
    """The autodoc directive of ``module_name.name``, a class (with its members) or a function."""
    kind = "autoclass" if inspect.isclass(getattr(importlib.import_module(module_name), name)) else "autofunction"
    return [f".. {kind}:: {module_name}.{name}", *(["   :members:"] if kind == "autoclass" else []), ""]


def module_section(module_name: str) -> list[str]:
    """One module's docstring and its public names (classes and functions; its data named in a line)."""
    module = importlib.import_module(module_name)
    names = public_names(module)
    data = [name for name in names if not callable(getattr(module, name))]
    lines = [f"### `{module_name}`", "", "```{eval-rst}", f".. automodule:: {module_name}", "   :no-index:", ""]
    for name in names:
        if name not in data:
            lines += directive(module_name, name)
    lines += ["```", ""]
    if data:  # autodoc would show their types' docstrings (a dict's), so only their names
        lines += ["Also exported: " + ", ".join(f"`{name}`" for name in data) + ".", ""]
    return lines


def write_api_page(app=None):
    """Write ``generated/api.md``."""
    lines = [
        "# API reference",
        "",
        "The public names of each package (its `__all__`), from their docstrings. Each env's own page "
        "([Environments](envs/index.md)) shows its spaces, config keys and metrics.",
        "",
    ]
    for title, modules in PUBLIC_MODULES.items():
        lines += [f"## {title}", ""]
        for module_name in modules:
            lines += module_section(module_name)
    return write_page("api", lines)


def markdown_headings_as_rubrics(app, what, name, obj, options, lines: list[str]) -> None:
    """An env docstring's Markdown sections (``## Action Space``, Gymnasium's layout, which the env pages show as
    headings) as reStructuredText rubrics in autodoc's output."""
    for index in reversed(range(len(lines))):
        heading = re.fullmatch(r"## (.+)", lines[index])
        if heading:
            lines[index : index + 1] = [f".. rubric:: {heading.group(1)}", ""]


def setup(app):
    app.connect("builder-inited", write_api_page)
    app.connect("autodoc-process-docstring", markdown_headings_as_rubrics)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
