"""Markdown table pieces the replay's reports share."""

from __future__ import annotations


def budget_cells(row: dict) -> tuple[str, str]:
    """The ``k`` and ``window [s]`` cells of a row (``-`` for the unbudgeted all-landmark policy)."""
    return ("-", "-") if row["k"] is None else (str(row["k"]), f"{row['window_s']:g}")


def table_lines(header, rows) -> list[str]:
    """A Markdown table's lines: the ``header`` cells, the rule under them, one line per row of cells."""
    return ["| " + " | ".join(cells) + " |" for cells in (header, ["---"] * len(header), *rows)]
