"""Sphinx configuration of the infonav-gym documentation (furo theme, MyST Markdown pages).

Build: ``python -m sphinx -W -b html docs docs/_build/html`` (``pip install ".[docs]"``). The build needs no
network: the pages are this folder's Markdown and the package's docstrings.
"""

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS.parent))  # the package beside the docs, not an installed copy
sys.path.insert(0, str(DOCS / "_ext"))  # this site's Sphinx extensions

import infonav_gym  # noqa: E402  (after the path above)

project = "infonav-gym"
author = "the infonav-gym authors"
copyright = "the infonav-gym authors, MIT licence"
release = version = infonav_gym.__version__

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon"]
extensions += [
    "env_pages",
    "api_page",
    "cli_page",
    "figures_page",
]  # docs/_ext: the pages in docs/generated, written at each build
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build"]
myst_heading_anchors = 3  # links to a page's sections: [text](page.md#section-title)

napoleon_google_docstring = True  # the code's docstrings are Google style (Args:, Returns:, Raises:)
napoleon_numpy_docstring = False

html_theme = "furo"
html_title = f"infonav-gym {release}"
