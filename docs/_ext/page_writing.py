"""What the generated pages share: where they go, Markdown tables and code spans, writing only what changed."""

from __future__ import annotations

from pathlib import Path

DOCS = Path(__file__).resolve().parent.parent
GENERATED = DOCS / "generated"  # pages written at each build (.gitignore)


def markdown_table(header: list[str], rows: list[list[str]]) -> list[str]:
    """A Markdown table; ``|`` inside a cell escaped."""
    lines = [header, ["---"] * len(header), *rows]
    return ["| " + " | ".join(str(cell).replace("|", "\\|") for cell in line) + " |" for line in lines]


def code(value) -> str:
    """``value`` as inline code (the backtick fence longer than any run of backticks inside)."""
    text = str(value).replace("\n", " ")
    fence = "``" if "`" in text else "`"
    return f"{fence}{text}{fence}"


def write_page(name: str, lines: list[str]) -> Path:
    """Write ``GENERATED/<name>.md`` unless it holds these lines already (Sphinx then keeps its cached build)."""
    path = GENERATED / f"{name}.md"
    path.parent.mkdir(parents=True, exist_ok=True)
    text = "\n".join(lines).rstrip() + "\n"
    if not path.is_file() or path.read_text() != text:
        path.write_text(text)
    return path
