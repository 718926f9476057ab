"""Sphinx extension: the command line page, every ``infonav`` subcommand read from its argparse parser.

Each command (and nested command, ``replay mrclam``) gets its one-line help, a table of its arguments and its
``--help`` text, so a new subcommand or option appears without editing the docs.
"""

from __future__ import annotations

import argparse

from page_writing import code, markdown_table, write_page

from infonav_gym.experiments.cli import build_parser

HELP_WIDTH = 100  # columns of the --help text


def subcommands(parser: argparse.ArgumentParser) -> dict[str, tuple[argparse.ArgumentParser, str]]:
    """``{name: (its parser, its one-line help)}`` of ``parser``'s subcommands, in the parser's order."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help for choice in action._choices_actions}
            return {name: (sub, helps.get(name) or "") for name, sub in action.choices.items()}
    return {}


def argument_rows(parser: argparse.ArgumentParser) -> list[list[str]]:
    """One row per argument: its flags (or name), its value, its help; subcommand choices and --help left out."""
    rows = []
    for action in parser._actions:
        if isinstance(action, (argparse._SubParsersAction, argparse._HelpAction)):
            continue
        name = ", ".join(action.option_strings) or action.dest
        takes = "" if action.nargs == 0 else action.metavar or action.dest.upper()
        rows.append([code(name), code(takes) if takes else "", action.help or ""])
    return rows


def help_text(parser: argparse.ArgumentParser) -> str:
    """``parser``'s ``--help`` at ``HELP_WIDTH`` columns (argparse reads them from ``COLUMNS``)."""
    formatter = parser.formatter_class
    parser.formatter_class = lambda prog: formatter(prog, width=HELP_WIDTH)
    try:
        return parser.format_help()
    finally:
        parser.formatter_class = formatter


def command_section(parser: argparse.ArgumentParser, summary: str, depth: int) -> list[str]:
    """The section of one command, then those of its subcommands one level deeper."""
    lines = [f"{'#' * depth} `{parser.prog}`", "", summary, ""]
    rows = argument_rows(parser)
    if rows:
        lines += [*markdown_table(["argument", "value", "what it does"], rows), ""]
    lines += ["```text", help_text(parser).rstrip(), "```", ""]
    for sub, sub_summary in subcommands(parser).values():
        lines += command_section(sub, sub_summary, depth + 1)
    return lines


def write_cli_page(app=None):
    """Write ``generated/cli.md``."""
    parser = build_parser()
    lines = [
        "# Command line",
        "",
        "The console script `infonav` (`pip install .`); every command takes `--help`, `--seed` and `--json` (one "
        "JSON object on stdout). This page is read from the parser itself (`infonav_gym.experiments.cli."
        "build_parser`).",
        "",
        *command_section(parser, parser.description or "", 1)[4:],  # the page's title stands for the top section's
    ]
    return write_page("cli", lines)


def setup(app):
    app.connect("builder-inited", write_cli_page)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
