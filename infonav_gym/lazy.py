"""Package namespaces whose names are imported from their modules when first asked for (PEP 562).

Importing one module of a package runs the package's ``__init__``: eager re-exports there would import
every sibling (and what they import, e.g. scipy.ndimage for terrain generation) for any one of them.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable


def lazy_exports(package: str, names: dict[str, tuple[str, ...]]) -> tuple[list[str], Callable[[str], object]]:
    """``(__all__, __getattr__)`` of ``package`` exporting ``names[module]`` of each of its submodules ``module``."""
    module_of = {name: module for module, exported in names.items() for name in exported}

    def __getattr__(name: str) -> object:
        if name in module_of:
            return getattr(importlib.import_module(f"{package}.{module_of[name]}"), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return sorted(module_of), __getattr__
