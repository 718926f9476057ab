"""Markdown table pieces the replay's reports share."""

from __future__ import annotations


def table_lines(header, rows) -> list[str]:
    """A Markdown table's lines: the ``header`` cells, the rule under them, one line per row of cells."""
    return ["| " + " | ".join(cells) + " |" for cells in (header, ["---"] * len(header), *rows)]
