"""The one place that makes a compiled kernel: numba's nopython dispatcher with an on-disk cache and IEEE arithmetic.

``@kernel`` compiles on the first call per set of argument types (literal values dropped) and caches the machine
code on disk (``_enable_caching``), keyed also on the sources of every kernel module (``kernel_sources_digest``:
numba's key alone would let a caller run a stale callee from another file). ``fastmath`` stays off (IEEE numbers,
x / 0 is inf); numba's parallel mode is off, and kernels release the GIL: ``CopyThreads`` runs one on chunks of
copies in threads. A compile longer than ``COMPILE_NOTICE_AFTER_S`` is announced once.
Kernels copy arrays element by element: slice assignment compiles numba's shape-error formatting (2 s more).
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
import tempfile
import threading
import weakref
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numba
import numpy as np
from numba.core import event, sigutils, types
from numba.core.caching import FunctionCache
from numba.core.registry import CPUDispatcher

COMPILE_NOTICE_AFTER_S = 1.0  # [s] a compile that takes longer is announced (once per process)
KERNEL_OPTIONS = {  # nogil: ``CopyThreads`` runs a kernel on several threads at once
    **{"cache": True, "fastmath": False, "parallel": False, "nogil": True},
    **{"error_model": "numpy", "no_cfunc_wrapper": True},
}
MIN_COPIES_PER_THREAD = 64  # fewer copies a thread and handing them over costs more than it saves

PACKAGE_ROOT = Path(__file__).resolve().parent
KERNEL_MODULE_MARK = b"infonav_gym.compiled import"  # what a module that makes kernels has in its imports

logger = logging.getLogger(__name__)
_kernels: weakref.WeakSet = weakref.WeakSet()  # the dispatchers made here: only their compiles are announced
_uncached_warned = False
_fallback_tried = False


class Kernel(CPUDispatcher):
    """numba's CPU dispatcher compiling for the argument types without their literal values (else a callee
    compiles once more per constant a caller passes)."""

    def compile(self, sig):
        args, return_type = sigutils.normalize_signature(sig)
        args = tuple(types.unliteral(arg) for arg in args)
        return super().compile(args if return_type is None else return_type(*args))

    def enable_caching(self):
        self._cache = SourcesKeyedCache(self.py_func)


@functools.cache
def kernel_sources_digest() -> str:
    """SHA-256 of this module and of every package module that makes kernels, read once per process."""
    digest = hashlib.sha256()
    for path in sorted(PACKAGE_ROOT.rglob("*.py")):
        source = path.read_bytes()
        if KERNEL_MODULE_MARK in source or path.name == "compiled.py" and path.parent == PACKAGE_ROOT:
            digest.update(path.relative_to(PACKAGE_ROOT).as_posix().encode() + b"\0" + source)
    return digest.hexdigest()


class SourcesKeyedCache(FunctionCache):
    """numba's on-disk cache of one kernel, its index key extended by ``kernel_sources_digest()``: a change in any
    kernel module makes every kernel compile again (once), instead of a caller running a stale callee."""

    def _index_key(self, sig, codegen):
        return (*super()._index_key(sig, codegen), kernel_sources_digest())


class InnerKernel(Kernel):
    """A ``Kernel`` compiled without numba's Python and C entry wrappers: only other kernels call it."""

    def __call__(self, *args, **kwargs):
        raise TypeError(f"{self.py_func.__qualname__} is an inner kernel: only other kernels can call it")


def kernel(function, dispatcher_class=Kernel, **options):
    """``function`` compiled by numba in nopython mode, cached on disk where a writable location exists
    (``_enable_caching``). ``dispatcher_class`` and ``options`` (more numba target options): ``inner_kernel``'s.
    """
    if numba.config.DISABLE_JIT:
        return function
    options = {key: value for key, value in {**KERNEL_OPTIONS, **options}.items() if key != "cache"}
    dispatcher = dispatcher_class(
        py_func=function, locals={}, targetoptions={**options, "nopython": True, "boundscheck": None}
    )
    if KERNEL_OPTIONS["cache"]:
        _enable_caching(dispatcher)
    _kernels.add(dispatcher)
    return dispatcher


def fallback_cache_dirs() -> list[Path]:
    """Where the kernels are cached when numba finds no writable location: the user's cache, then a temporary
    directory (kept across runs until the system clears it)."""
    user_cache = Path(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"))
    return [user_cache / "infonav-gym" / "numba", Path(tempfile.gettempdir()) / "infonav-gym-numba"]


def _writable_directory(path: Path) -> bool:
    """Whether ``path`` is, or is now made, a directory a file can be written into (a probe file, removed)."""
    try:
        path.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError:
        return False
    return True


def _enable_caching(dispatcher) -> None:
    """numba's on-disk cache for ``dispatcher``; where numba has no writable location (it raises ``RuntimeError``
    "no locator available"), the first writable ``fallback_cache_dirs()`` becomes ``NUMBA_CACHE_DIR`` (tried once
    per process); where none is, the kernel is compiled on every start. Each fallback is said once."""
    global _fallback_tried, _uncached_warned
    try:
        dispatcher.enable_caching()
        return
    except RuntimeError as error:
        if "no locator available" not in str(error):
            raise
        reason = error
    if not _fallback_tried:
        _fallback_tried = True
        directory = next((path for path in fallback_cache_dirs() if _writable_directory(path)), None)
        if directory is not None:
            os.environ["NUMBA_CACHE_DIR"] = numba.config.CACHE_DIR = str(directory)  # numba reads config.CACHE_DIR
            logger.warning(
                "infonav_gym: neither the package's directory nor numba's user-wide cache is writable; "
                "the kernels are cached in %s (set NUMBA_CACHE_DIR to choose)",
                directory,
            )
            return _enable_caching(dispatcher)
    if not _uncached_warned:
        _uncached_warned = True
        compile_notice.cached = False
        logger.warning(
            "infonav_gym: no writable numba cache location (set NUMBA_CACHE_DIR to a writable directory); "
            "kernels are compiled on every start: %s",
            reason,
        )


def inner_kernel(function):
    """A ``kernel`` that only other kernels call: numba's Python entry wrapper, which a kernel-to-kernel call does not
    use, is not compiled (less to compile on a first use); a call from Python raises ``TypeError``."""
    return kernel(function, InnerKernel, no_cpython_wrapper=True)


def inlined_kernel(function):
    """A ``kernel`` that kernels calling it compile into themselves (numba's ``inline="always"``): no library of its
    own for numba to link into each caller and optimize once more at each level of a call chain."""
    return kernel(function, inline="always")


def inline(function):
    """An ``inner_kernel`` that LLVM inlines into each kernel calling it (numba's ``forceinline``): a small helper of
    hot loops, compiled once rather than typed again at each call site (numba's ``inline="always"`` would)."""
    return kernel(function, InnerKernel, no_cpython_wrapper=True, forceinline=True)


class CopyThreads:
    """Runs a kernel over N copies in up to ``count`` chunks of rows at once, one per thread (the kernels release the
    GIL). Each copy's arithmetic is its own, so the numbers are those of one call over all copies, bit for bit."""

    def __init__(self, count: int = 1):
        self.count, self._pool = count, None

    def map_rows(self, kernel_, n_copies: int, per_copy: tuple, shared: tuple = ()):
        """``kernel_(*per_copy, *shared)``: ``per_copy`` holds arrays with a leading copy dimension (nested in tuples;
        other items pass whole), split in chunks of rows; the chunks' outputs joined (``joined_rows``)."""
        chunks = min(self.count, n_copies // MIN_COPIES_PER_THREAD)
        if chunks <= 1:
            return kernel_(*per_copy, *shared)
        if self._pool is None:
            self._pool = ThreadPoolExecutor(self.count, thread_name_prefix="infonav-copies")
        bounds = np.linspace(0, n_copies, chunks + 1).astype(int).tolist()
        parts = [rows_of(per_copy, slice(start, end)) for start, end in zip(bounds[:-1], bounds[1:])]
        others = [self._pool.submit(kernel_, *part, *shared) for part in parts[1:]]
        first = kernel_(*parts[0], *shared)  # in this thread while the others run
        return joined_rows([first, *(other.result() for other in others)])

    def __getstate__(self):
        return {"count": self.count, "_pool": None}  # a pool does not pickle: the copy makes its own


def rows_of(value, rows: slice):
    """``value``'s ``rows`` (a view): of each array in nested tuples, the others as they are."""
    if isinstance(value, tuple):
        return tuple(rows_of(item, rows) for item in value)
    return value[rows] if isinstance(value, np.ndarray) else value


def joined_rows(parts: list):
    """The outputs of chunks of rows as one: arrays concatenated along the copies, flags (bools) or-ed, tuples item
    by item."""
    first = parts[0]
    if isinstance(first, tuple):
        return tuple(joined_rows([part[index] for part in parts]) for index in range(len(first)))
    if isinstance(first, np.ndarray):
        return np.concatenate(parts)
    if isinstance(first, (bool, np.bool_)):
        return any(parts)
    raise TypeError(f"joined_rows: cannot join {type(first).__name__} outputs of chunks of copies")


def contiguous(array):
    """An ndarray as the one array layout the kernels are compiled for: itself if C-contiguous and writeable, else a
    copy (a read-only or strided view, e.g. from ``np.broadcast_to``, would be another numba type: another compile)."""
    flags = array.flags
    return array if flags.c_contiguous and flags.writeable else array.copy()


def stacked(value, shape: tuple[int, ...]) -> np.ndarray:
    """A new C-contiguous float64 array of ``shape`` holding ``value`` broadcast: what the kernels take, in one copy
    (not ``np.broadcast_to``, a read-only view, then a copy)."""
    array = np.empty(shape)
    array[...] = value
    return array


class _CompileNotice(event.Listener):
    """Says once that kernels are being compiled when an outermost compile of ours runs past the threshold (numba's
    compiler lock makes compiles nest, never overlap)."""

    def __init__(self):
        self.depth, self.timer, self.said = 0, None, False
        self.cached = True  # False once kernels run uncached: the notice says so

    def on_start(self, event_):
        if self.depth == 0 and not self.said and event_.data["dispatcher"] in _kernels:
            self.timer = threading.Timer(COMPILE_NOTICE_AFTER_S, self.say)
            self.timer.daemon = True
            self.timer.start()
        self.depth += 1

    def on_end(self, event_):
        self.depth -= 1
        if self.depth == 0 and self.timer is not None:
            self.timer.cancel()
            self.timer = None

    def say(self):
        if not self.said:
            self.said = True
            when = "first use; cached for later runs" if self.cached else "not cached: on every start"
            logger.warning("infonav_gym: compiling the numba kernels (%s) ...", when)


compile_notice = _CompileNotice()
event.register("numba:compile", compile_notice)


INTERRUPTIONS = (KeyboardInterrupt, SystemError)  # what Ctrl-C raises: see ``pressed_ctrl_c``


def pressed_ctrl_c(error: BaseException) -> bool:
    """Whether ``error`` is Ctrl-C: a ``KeyboardInterrupt``, or the ``SystemError`` a kernel call raises when one
    arrives while numba runs Python inside it (the interrupt is then in the error's chain)."""
    while error is not None:
        if isinstance(error, KeyboardInterrupt):
            return True
        error = error.__cause__ or error.__context__
    return False
