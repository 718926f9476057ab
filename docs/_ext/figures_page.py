"""Sphinx extension: the paper's figures as reproduced (``results/fig*.png``), each with the command that makes it.

The commands are read from the table in ``results/README.md`` (a file's row: its name, then its command), so the
page says what that file says; a figure without a row there fails the build.
"""

from __future__ import annotations

import re

from page_writing import DOCS, write_page

RESULTS = DOCS.parent / "results"


def regenerating_commands() -> dict[str, str]:
    """``{file stem: command}`` from ``results/README.md``'s table (its first cell names the files by stem)."""
    commands = {}
    for row in re.findall(r"^\| `([^`]+)`[^|]* \| (.+) \|$", (RESULTS / "README.md").read_text(), flags=re.M):
        stem = row[0].rpartition("/")[2].split(".")[0]
        commands[stem] = row[1]
    return commands


def write_figures_page(app=None):
    """Write ``generated/figures.md``: every ``results/fig*.png`` with its command."""
    commands = regenerating_commands()
    lines = [
        "# The paper's figures",
        "",
        "The figures of *Quantifying Uncertainty Towards Information-Centric Unmanned Navigation* as this suite "
        "reproduces them (committed in `results/`), each with the command that regenerates it, from "
        "`results/README.md` (run from the repository root). The [results page](../results.md) discusses each "
        "against the paper.",
        "",
    ]
    for figure in sorted(RESULTS.glob("fig*.png"), key=lambda path: int(re.sub(r"\D", "", path.stem))):
        if figure.stem not in commands:
            raise ValueError(f"results/README.md has no command for {figure.name}; add its row")
        number = re.sub(r"\D", "", figure.stem)
        lines += [
            f"## Fig. {number}",
            "",
            f"Regenerate with {commands[figure.stem]}.",
            "",
            f"![Fig. {number} reproduced](../../results/{figure.name})",
            "",
        ]
    return write_page("figures", lines)


def setup(app):
    app.connect("builder-inited", write_figures_page)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
