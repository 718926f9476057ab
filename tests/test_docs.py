"""The documentation site builds with warnings as errors (``python -m sphinx -W -b html docs docs/_build/html``)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"


def test_docs_build_without_warnings(tmp_path):
    pytest.importorskip("sphinx", reason='the docs need Sphinx: pip install ".[docs]"')
    pytest.importorskip("furo", reason='the docs need the furo theme: pip install ".[docs]"')
    pytest.importorskip("myst_parser", reason='the docs need myst-parser: pip install ".[docs]"')
    built = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(DOCS), str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert built.returncode == 0, built.stderr[-4000:]
    assert (tmp_path / "index.html").is_file()
