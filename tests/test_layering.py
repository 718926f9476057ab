"""The package's layers, read from the source with ``ast`` (nothing is imported).

- The core (every ``infonav_gym`` module outside ``infonav_gym.experiments``) never imports
  ``agents`` nor the harness ``infonav_gym.experiments``, at module level or inside a function.
- ``agents`` imports only the core: never the harness.
- No import cycle: see ``test_no_import_cycle_between_the_packages_modules``.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("infonav_gym", "agents")
HARNESS = "infonav_gym.experiments"


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {module_name(path): path for package in PACKAGES for path in sorted((ROOT / package).rglob("*.py"))}


def within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def _absolute(node: ast.ImportFrom, module: str) -> str:
    """The module a ``from ... import`` names, relative imports resolved against ``module``."""
    if not node.level:
        return node.module
    package = module.split(".") if MODULES[module].name == "__init__.py" else module.split(".")[:-1]
    base = package[: len(package) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def imports(module: str, inside_functions: bool = True, type_checking: bool = True) -> list[tuple[str, int]]:
    """``(imported module, line)`` for every import in ``module``, those inside functions unless
    ``inside_functions`` is false, those under ``if TYPE_CHECKING:`` (which never run) unless ``type_checking`` is.

    ``from a import b`` counts as importing ``a.b`` when that is a module of the packages, else ``a``.
    """
    tree = ast.parse(MODULES[module].read_text(), filename=str(MODULES[module]))
    found = []

    def visit(node: ast.AST) -> None:
        if not inside_functions and isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            return
        if not type_checking and isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            found.extend((alias.name, node.lineno) for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(node, module)
            for alias in node.names:
                name = f"{base}.{alias.name}"
                found.append((name if name in MODULES else base, node.lineno))
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return found


def forbidden_imports(package: str, excluded: str | None, forbidden: tuple[str, ...]) -> list[str]:
    """``"module:line imports target"`` for every import of ``forbidden`` in ``package`` (minus ``excluded``)."""
    return [
        f"{MODULES[module].relative_to(ROOT)}:{line} imports {target}"
        for module in MODULES
        if within(module, package) and not (excluded and within(module, excluded))
        for target, line in imports(module)
        if any(within(target, name) for name in forbidden)
    ]


def test_the_core_never_imports_agents_nor_the_harness():
    found = forbidden_imports("infonav_gym", HARNESS, ("agents", HARNESS))
    assert found == [], "the core imports a higher layer:\n" + "\n".join(found)


def test_agents_import_only_the_core_not_the_harness():
    found = forbidden_imports("agents", None, (HARNESS,))
    assert found == [], "agents imports the harness:\n" + "\n".join(found)


def test_the_checks_find_an_import_inside_a_function(tmp_path, monkeypatch):
    """The scan itself: a core module importing the harness inside a function is named with its line."""
    source = tmp_path / "infonav_gym" / "sneaky.py"
    source.parent.mkdir()
    source.write_text('"""x"""\n\n\ndef f():\n    from infonav_gym.experiments import cli\n')
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    monkeypatch.setattr(f"{__name__}.MODULES", {"infonav_gym.sneaky": source})
    assert forbidden_imports("infonav_gym", HARNESS, ("agents", HARNESS)) == [
        "infonav_gym/sneaky.py:5 imports infonav_gym.experiments"
    ]
    assert imports("infonav_gym.sneaky", inside_functions=False) == []


def import_graph() -> dict[str, set[str]]:
    """The modules of the packages each module imports when it runs, inside functions too (edges to the named
    module only)."""
    graph = {}
    for module in MODULES:
        graph[module] = {target for target, _ in imports(module, type_checking=False) if target in MODULES} - {module}
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One import cycle of ``graph`` as ``[a, b, ..., a]``, or ``None``."""
    state: dict[str, str] = {}  # "open" while on the current path, "done" after
    path: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = "open"
        path.append(node)
        for target in sorted(graph[node]):
            if state.get(target) == "open":
                return path[path.index(target) :] + [target]
            if target not in state and (cycle := visit(target)):
                return cycle
        state[node] = "done"
        path.pop()
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def test_no_import_cycle_between_the_packages_modules():
    """No cycle among the imports of ``infonav_gym`` and ``agents``, those inside functions included.

    An edge ``a -> b`` is an import of module ``b`` in ``a`` that can run (at module level or inside a function;
    not under ``if TYPE_CHECKING``): an import deferred into a function hides a cycle, it does not remove it.
    Only the named module counts, not the packages above it that Python imports first: a package ``__init__``
    re-exporting its modules is no cycle.
    """
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle)


@pytest.mark.parametrize(
    "graph, expected",
    [
        ({"a": {"b"}, "b": {"c"}, "c": set()}, None),
        ({"a": {"b"}, "b": {"c"}, "c": {"a"}}, ["a", "b", "c", "a"]),
        ({"a": set(), "b": {"c"}, "c": {"b"}}, ["b", "c", "b"]),
    ],
)
def test_find_cycle_finds_a_cycle_exactly_when_there_is_one(graph, expected):
    assert find_cycle(graph) == expected


ENVS = "infonav_gym.envs"


def env_folders() -> list[str]:
    """The env folders: the packages right below ``infonav_gym.envs`` (one per env)."""
    return sorted(
        module for module, path in MODULES.items() if path.name == "__init__.py" and module.rsplit(".", 1)[0] == ENVS
    )


def cross_env_imports() -> list[str]:
    """``"module:line imports target"`` for every import of one env folder's module in another env folder."""
    folders = env_folders()
    return [
        f"{MODULES[module].relative_to(ROOT)}:{line} imports {target}"
        for folder in folders
        for module in MODULES
        if within(module, folder)
        for target, line in imports(module)
        if any(within(target, other) for other in folders if other != folder)
    ]


def test_each_built_in_env_is_one_folder():
    """Every built-in env's vector env (its driver bound to its scenario) lives in its own folder below
    ``infonav_gym.envs``: one env, one folder."""
    from infonav_gym.registry import registered_envs

    homes = {}
    for entry in registered_envs():
        module = entry.load_vector().__module__
        if within(module, "infonav_gym"):  # not an env a test registered
            homes[entry.id] = ".".join(module.split(".")[:3])
    assert len(homes) >= 6 and len(set(homes.values())) == len(homes), homes
    assert all(home in env_folders() for home in homes.values()), homes


def test_no_env_folder_imports_another():
    found = cross_env_imports()
    assert found == [], "an env folder imports another:\n" + "\n".join(found)


def test_the_env_folder_check_finds_an_import_of_another_env(tmp_path, monkeypatch):
    """The scan itself: a module of one env folder importing another env folder's module is named with its line."""
    for name, source in (("a", '"""x"""\nfrom infonav_gym.envs.b import thing\n'), ("b", '"""x"""\nthing = 1\n')):
        folder = tmp_path / "infonav_gym" / "envs" / name
        folder.mkdir(parents=True)
        (folder / "__init__.py").write_text(source)
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    found = {f"{ENVS}.{name}": tmp_path / "infonav_gym" / "envs" / name / "__init__.py" for name in "ab"}
    monkeypatch.setattr(f"{__name__}.MODULES", found)
    assert cross_env_imports() == ["infonav_gym/envs/a/__init__.py:2 imports infonav_gym.envs.b"]
