"""Write the command-line reference page (``reference/cli.md``) from the ``kinegrasp``
argparse parser itself (``kinegrasp_env.cli.main.build_parser``): every command and
sub-command, its usage, description and options with their defaults and choices.

Run by mkdocs-gen-files during ``mkdocs build``; nothing here is typed by hand.
"""

from __future__ import annotations

import argparse

import mkdocs_gen_files

from kinegrasp_env.cli.main import build_parser


def _cell(text: object) -> str:
    """Text for a Markdown table cell (pipes escaped, one line)."""
    return " ".join(str(text).split()).replace("|", "\\|")


def _subcommands(parser: argparse.ArgumentParser):
    """(name, one-line help, parser) of each sub-command of ``parser``, in parser order."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {choice.dest: choice.help or "" for choice in action._choices_actions}
            for name, sub in action.choices.items():
                yield name, helps.get(name, ""), sub


def _options_table(parser: argparse.ArgumentParser) -> list[str]:
    """A Markdown table of the parser's arguments (help, sub-command groups left out)."""
    formatter = parser._get_formatter()
    rows = []
    for action in parser._actions:
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        if action.help == argparse.SUPPRESS:
            continue
        if action.option_strings:
            name = ", ".join(f"`{s}`" for s in action.option_strings)
            if action.nargs != 0:
                name += f" `{formatter._format_args(action, action.dest.upper())}`"
        else:
            name = f"`{action.metavar or action.dest}`"
        help_text = formatter._expand_help(action) if action.help else ""
        default = action.default
        shown = ("" if default in (None, argparse.SUPPRESS, False) or not action.option_strings
                 else f"`{default}`")
        choices = ", ".join(f"`{c}`" for c in action.choices) if action.choices else ""
        rows.append(f"| {_cell(name)} | {_cell(help_text)} | {_cell(shown)} | {_cell(choices)} |")
    if not rows:
        return []
    return ["| argument | meaning | default | choices |", "|---|---|---|---|", *rows, ""]


def _section(name: str, summary: str, parser: argparse.ArgumentParser, level: int) -> list[str]:
    lines = [f"{'#' * level} `{name}`", ""]
    text = parser.description or summary
    if text:
        lines += [" ".join(text.split()), ""]
    lines += ["```text", parser.format_usage().strip(), "```", ""]
    lines += _options_table(parser)
    if parser.epilog:
        lines += [" ".join(parser.epilog.split()), ""]
    for sub_name, sub_summary, sub in _subcommands(parser):
        lines += _section(f"{name} {sub_name}", sub_summary, sub, min(level + 1, 4))
    return lines


def page() -> str:
    """The whole reference page."""
    parser = build_parser()
    lines = ["# Command line", "",
             "Generated from the `kinegrasp` command's own parser: what `kinegrasp COMMAND "
             "--help` prints, as tables. Bad input is reported in one line with exit status 2. "
             "`-h`, `--help` on any command prints its help.", "",
             "```text", parser.format_usage().strip(), "```", "",
             *_options_table(parser),
             "| command | what it does |", "|---|---|"]
    for name, summary, _ in _subcommands(parser):
        anchor = f"kinegrasp-{name}".replace(" ", "-")
        lines.append(f"| [`{name}`](#{anchor}) | {_cell(summary)} |")
    lines.append("")
    for name, summary, sub in _subcommands(parser):
        lines += _section(f"kinegrasp {name}", summary, sub, 2)
    return "\n".join(lines) + "\n"


with mkdocs_gen_files.open("reference/cli.md", "w") as handle:
    handle.write(page())
