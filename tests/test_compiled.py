"""``infonav_gym.compiled``: kernels cached on disk where any location is writable (a read-only install uses
``NUMBA_CACHE_DIR`` or numba's user-wide cache), uncached after one warning line where none is, IEEE
arithmetic, and one notice when a first compile takes long."""

import logging
import os
import shutil
import stat
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numba
import numpy as np
import pytest
from numba.core.caching import FunctionCache

from infonav_gym import compiled
from infonav_gym.estimation import kernels
from infonav_gym.information import log_det_spd

PACKAGE = Path(compiled.__file__).resolve().parent
UNCACHED_WARNING = "no writable numba cache location"

# Run in a read-only copy of the package: one kernel (information's log det) on a 2 x 2 and a 4 x 4 stack;
# prints the log dets and how many of that kernel's signatures came from the disk cache.
PROBE = textwrap.dedent(
    """
    import sys
    from pathlib import Path
    import numpy as np
    from infonav_gym import compiled
    if len(sys.argv) > 2:  # the fallback cache directories instead of the user's cache and the temporary directory
        compiled.fallback_cache_dirs = lambda: [Path(sys.argv[2])]
    from infonav_gym import information
    assert information.__file__.startswith(sys.argv[1]), information.__file__
    print(information.log_det_spd(np.stack([np.diag([2.0, 3.0]), np.eye(2)]), check_input=False).tolist())
    print(information.log_det_spd(np.eye(4)[None] * 2.0, check_input=False).tolist())
    print(sum(information.stacked_log_dets.stats.cache_hits.values()))
    """
)


def read_only_install(root: Path) -> Path:
    """A copy of the package under ``root`` that nothing can be written into (as root too: every ``__pycache__``
    is a plain file, so no directory can be made there); the directory to put on ``PYTHONPATH``."""
    site = root / "site"
    shutil.copytree(PACKAGE, site / "infonav_gym", ignore=shutil.ignore_patterns("__pycache__"))
    for directory in [site, *(path for path in site.rglob("*") if path.is_dir())]:
        (directory / "__pycache__").write_text("not a directory")
    for path in [site, *site.rglob("*")]:
        path.chmod(path.stat().st_mode & ~(stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))
    return site


def unwritable(root: Path) -> Path:
    """A path no one can make a directory at: it lies under a plain file."""
    blocker = root / "plain_file"
    blocker.write_text("")
    return blocker / "cache"


def run_probe(site: Path, *fallback: Path, **environment) -> subprocess.CompletedProcess:
    env = {key: value for key, value in os.environ.items() if not key.startswith(("NUMBA_", "XDG_"))}
    env.update(PYTHONPATH=str(site), PYTHONDONTWRITEBYTECODE="1", **environment)
    argv = [sys.executable, "-c", PROBE, str(site), *map(str, fallback)]
    done = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=site, timeout=300)
    assert done.returncode == 0, done.stderr
    return done


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    root = tmp_path_factory.mktemp("install")
    yield read_only_install(root)
    for path in [root, *root.rglob("*")]:  # let pytest clean it up
        path.chmod(path.stat().st_mode | stat.S_IWUSR)


def expected_lines() -> list[str]:
    return [str([float(np.log(6.0)), 0.0]), str([float(4 * np.log(2.0))])]


def test_a_read_only_install_caches_its_kernels_in_numba_cache_dir(site, tmp_path):
    cache = tmp_path / "numba_cache"
    first = run_probe(site, NUMBA_CACHE_DIR=str(cache), XDG_CACHE_HOME=str(unwritable(tmp_path)))
    assert first.stdout.split("\n")[:3] == [*expected_lines(), "0"]
    assert list(cache.rglob("*.nbi")), "no cache index written to NUMBA_CACHE_DIR"
    second = run_probe(site, NUMBA_CACHE_DIR=str(cache), XDG_CACHE_HOME=str(unwritable(tmp_path)))
    assert second.stdout.split("\n")[:3] == [*expected_lines(), "1"]  # loaded from the cache, not compiled
    assert UNCACHED_WARNING not in first.stderr + second.stderr


def test_a_read_only_install_falls_back_to_numbas_user_wide_cache(site, tmp_path):
    user_cache = tmp_path / "user_cache"
    run_probe(site, XDG_CACHE_HOME=str(user_cache))
    again = run_probe(site, XDG_CACHE_HOME=str(user_cache))
    assert again.stdout.split("\n")[:3] == [*expected_lines(), "1"]
    assert list((user_cache / "numba").rglob("*.nbi"))


def test_a_read_only_install_without_a_user_cache_caches_its_kernels_in_a_temporary_directory(site, tmp_path):
    """Neither the package's directory nor numba's user-wide cache is writable: the temporary directory it is."""
    blocked, temporary = unwritable(tmp_path), tmp_path / "tmp"
    temporary.mkdir()
    first, second = (run_probe(site, XDG_CACHE_HOME=str(blocked), TMPDIR=str(temporary)) for _ in range(2))
    assert first.stdout.split("\n")[:3] == [*expected_lines(), "0"]
    assert second.stdout.split("\n")[:3] == [*expected_lines(), "1"]  # loaded from the cache, not compiled
    said = f"the kernels are cached in {temporary / 'infonav-gym-numba'} (set NUMBA_CACHE_DIR to choose)"
    assert said in first.stderr and UNCACHED_WARNING not in first.stderr + second.stderr
    assert list((temporary / "infonav-gym-numba").rglob("*.nbi"))


def test_without_any_writable_cache_location_kernels_run_uncached_after_one_warning_line(site, tmp_path):
    blocked = unwritable(tmp_path)
    done = run_probe(site, blocked, NUMBA_CACHE_DIR=str(blocked), XDG_CACHE_HOME=str(blocked))
    assert done.stdout.split("\n")[:3] == [*expected_lines(), "0"]
    warnings = [line for line in done.stderr.splitlines() if UNCACHED_WARNING in line]
    assert len(warnings) == 1, done.stderr
    assert "NUMBA_CACHE_DIR" in warnings[0]


CALLEE = "from infonav_gym.compiled import kernel\n\n\n@kernel\ndef offset(value):\n    return value + {}\n"
CALLER = """from infonav_gym.compiled import kernel
from infonav_gym.probe_callee import offset


@kernel
def doubled_offset(value):
    return 2.0 * offset(value)
"""


def test_a_cached_kernel_compiles_again_when_a_kernel_it_calls_changes_in_another_file(tmp_path):
    """numba keys its cache on the function's own bytecode: without the package's sources in the key, the caller
    would keep running the old callee it was cached with."""
    site = tmp_path / "site"
    shutil.copytree(PACKAGE, site / "infonav_gym", ignore=shutil.ignore_patterns("__pycache__"))
    (site / "infonav_gym" / "probe_caller.py").write_text(CALLER)
    env = {key: value for key, value in os.environ.items() if not key.startswith(("NUMBA_", "XDG_"))}
    env.update(PYTHONPATH=str(site), NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    probe = "from infonav_gym.probe_caller import doubled_offset; print(doubled_offset(1.0))"
    printed = []
    for offset in ("1.0", "2.0", "2.0"):
        (site / "infonav_gym" / "probe_callee.py").write_text(CALLEE.format(offset))
        done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, cwd=site)
        assert done.returncode == 0, done.stderr
        printed.append(done.stdout.strip())
    assert printed == ["4.0", "6.0", "6.0"]
    assert len(list((tmp_path / "cache").rglob("*.nbc"))) >= 2  # cached, not merely compiled each time


def test_the_uncached_fallback_warns_once_for_many_kernels_and_the_compile_notice_says_so(monkeypatch, caplog):
    """numba's "no locator available" at decoration (here: no locator at all) makes uncached kernels, one warning."""
    monkeypatch.setattr(numba.core.caching.CacheImpl, "_locator_classes", [])
    monkeypatch.setattr(compiled, "fallback_cache_dirs", lambda: [])
    monkeypatch.setattr(compiled, "_fallback_tried", False)
    monkeypatch.setattr(compiled, "_uncached_warned", False)
    monkeypatch.setattr(compiled, "compile_notice", compiled._CompileNotice())
    with caplog.at_level(logging.WARNING, logger=compiled.__name__):
        twice = compiled.kernel(lambda value: 2.0 * value)
        thrice = compiled.kernel(lambda value: 3.0 * value)
        assert (twice(1.5), thrice(1.5)) == (3.0, 4.5)
        compiled.compile_notice.say()
    messages = [record.getMessage() for record in caplog.records]
    assert sum(message.count(UNCACHED_WARNING) for message in messages) == 1
    assert messages[-1] == "infonav_gym: compiling the numba kernels (not cached: on every start) ..."


def test_a_long_first_compile_is_announced_once(monkeypatch, caplog):
    monkeypatch.setitem(compiled.KERNEL_OPTIONS, "cache", False)  # a real compile every run, not a cache load
    monkeypatch.setattr(compiled.compile_notice, "said", False)

    def announcements() -> list[str]:
        messages = [record.getMessage() for record in caplog.records]
        return [message for message in messages if "compiling the numba kernels" in message]

    with caplog.at_level(logging.WARNING, logger=compiled.__name__):
        monkeypatch.setattr(compiled, "COMPILE_NOTICE_AFTER_S", 60.0)
        assert compiled.kernel(lambda value: value + 1.0)(1.0) == 2.0  # well under a minute: no word
        assert announcements() == []
        monkeypatch.setattr(compiled, "COMPILE_NOTICE_AFTER_S", 0.0)
        assert compiled.kernel(lambda value: value + 2.0)(1.0) == 3.0
        deadline = time.monotonic() + 5.0
        while not announcements() and time.monotonic() < deadline:  # the notice comes from a timer thread
            time.sleep(0.01)
        assert compiled.kernel(lambda value: value + 3.0)(1.0) == 4.0
    assert len(announcements()) == 1


def test_the_packages_kernels_are_cached_on_disk_with_ieee_arithmetic():
    for dispatcher in (kernels.kalman_updates, kernels.predict_poses, kernels.landmark_gains):
        assert isinstance(dispatcher._cache, FunctionCache)  # numba's on-disk cache, not its NullCache
        assert dispatcher.targetoptions["fastmath"] is False and not dispatcher.targetoptions["parallel"]
    predicted, _, _ = kernels.range_bearing_models(np.array([[0.0, 0.0, np.inf]]), np.array([[[1.0, 0.0]]]), False)
    assert np.isnan(predicted[0, 0, 1])  # the bearing wrapped from an infinite heading: NaN, as numpy's remainder gives
    with pytest.raises(ValueError, match="not positive definite"):
        log_det_spd(np.array([[[1.0, 2.0], [2.0, 1.0]]]), check_input=False)


def test_a_kernel_compiles_once_whatever_constants_it_is_called_with():
    """Literal values are dropped from the argument types: a kernel called by another with constants (and with a
    counter that type inference first sees as its initial ``0``) and from Python has one specialization."""
    scaled = compiled.kernel(lambda value, times, flag: value * times if flag else -value)

    @compiled.kernel
    def caller(value):
        count = 0
        for _ in range(3):
            count += 1
        return scaled(value, 2, True) + scaled(value, count, False)

    assert (caller(1.5), scaled(1.5, 4, True)) == (1.5, 6.0)
    assert scaled.signatures == [(numba.float64, numba.int64, numba.boolean)]


def test_an_inner_kernel_runs_inside_kernels_and_refuses_a_call_from_python():
    halved = compiled.inner_kernel(lambda value: 0.5 * value)
    assert compiled.kernel(lambda value: halved(value) + 1.0)(3.0) == 2.5
    with pytest.raises(TypeError, match="is an inner kernel: only other kernels can call it"):
        halved(3.0)


def test_ctrl_c_inside_a_kernel_call_is_recognized_through_the_system_error_numba_raises():
    def raised(error, cause=None):
        try:
            raise error from cause
        except BaseException as caught:  # noqa: BLE001  (the test builds the chains)
            return caught

    inside_kernel = raised(SystemError("returned a result with an exception set"), raised(KeyboardInterrupt()))
    assert compiled.pressed_ctrl_c(KeyboardInterrupt()) and compiled.pressed_ctrl_c(inside_kernel)
    assert not compiled.pressed_ctrl_c(SystemError("a real one"))
    assert not compiled.pressed_ctrl_c(raised(SystemError(), ValueError()))
