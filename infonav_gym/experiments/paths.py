"""Output paths of the harness: checked before the work starts; a write failure and an interruption that keep the
work."""

from __future__ import annotations

import tempfile
from pathlib import Path


class KeptWork:
    """An exception carrying the work done: ``result``."""

    def __init__(self, message: str, result: dict):
        super().__init__(message)
        self.result = result


class OutputWriteError(KeptWork, Exception):
    """Writing the files failed after the work was done; ``result`` holds the work (its ``files``: those written)."""


class Interrupted(KeptWork, KeyboardInterrupt):
    """Ctrl-C stopped the work; ``result`` holds what was finished (``"interrupted": True``)."""


def _check_directory(directory: Path, where: str) -> None:
    """``ValueError`` starting ``where:`` unless ``directory`` is, or can be created as, a writable directory."""
    existing = next((path for path in (directory, *directory.parents) if path.exists()), Path("."))
    if not existing.is_dir():
        raise ValueError(f"{where}: {existing} is a file, not a directory")
    try:  # a real write, not os.access: root passes os.access where the file system refuses (read-only, /proc)
        tempfile.TemporaryFile(dir=existing).close()  # unnamed or removed at once: nothing stays
    except OSError as error:
        action = f"write to {existing}" if existing == directory else f"create {directory} in {existing}"
        raise ValueError(f"{where}: cannot {action} ({error.strerror or error})") from None


def check_output_dir(directory: Path | str, where: str) -> Path:
    """``directory``, once seen to be, or creatable as, a writable directory (else ``ValueError`` naming ``where``)."""
    directory = Path(directory)
    _check_directory(directory, f"{where} {directory}")
    return directory


def output_file(stem: Path, suffix: str) -> Path:
    """``stem`` + ``suffix``, the whole stem kept: ``out/eval.v2`` -> ``out/eval.v2.md`` (``with_suffix`` would cut)."""
    return stem.with_name(stem.name + suffix)


def check_output_stem(stem: Path | str, suffixes: tuple[str, ...], where: str) -> Path:
    """The stem of files ``stem`` + each of ``suffixes``, once they are seen to be writable (else ``ValueError`` naming
    ``where``); a trailing one of ``suffixes`` is dropped (``results/eval.md`` -> ``results/eval``)."""
    stem = Path(stem)
    if stem.suffix and stem.suffix in suffixes:
        stem = stem.with_suffix("")
    if stem.is_dir():
        raise ValueError(f"{where} {stem} is a directory: give a file stem, e.g. {stem / 'results'}")
    _check_directory(stem.parent, f"{where} {stem}")
    for suffix in suffixes:
        path = output_file(stem, suffix)
        if path.is_dir():
            raise ValueError(f"{where} {stem}: {path} is a directory, not a file")
        try:
            if path.exists():
                path.open("ab").close()  # can it be overwritten? opened to append, nothing written
        except OSError as error:
            raise ValueError(f"{where} {stem}: cannot overwrite {path} ({error.strerror or error})") from None
    return stem


def write_failure(what: str, error: OSError) -> str:
    """One line for a failed write: what could not be written and the OS's reason."""
    reason = error.strerror or str(error)
    name = f" {error.filename}" if error.filename else ""
    return f"could not write {what}:{name} {reason}"
