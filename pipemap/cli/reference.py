"""The command-line reference, written from the parser itself so that it cannot drift.

``python -m pipemap.cli.reference > docs/cli.md`` regenerates ``docs/cli.md``; a
test fails when the file and the parser disagree (a flag added, renamed or
documented differently), so every flag the parser accepts is in the manual.
"""

from __future__ import annotations

import argparse
import sys

from pipemap.cli.parser import build_parser

__all__ = ["reference_markdown"]

_HEADER = """\
# Command-line reference

Generated from pipemap's argument parser by `python -m pipemap.cli.reference >
docs/cli.md`; `tests/test_cli_reference.py` fails when this page and the parser
disagree. Every command reports a bad argument, a missing or malformed input or an
unwritable output as one line, `pipemap: error: ...`, with exit status 2.
"""


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _summaries(parser: argparse.ArgumentParser) -> dict[str, str]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return {a.dest: a.help or "" for a in action._choices_actions}
    return {}


def _cell(text: str) -> str:
    return " ".join(text.split()).replace("|", "\\|")


def _default(action: argparse.Action) -> str:
    if action.required or action.default in (None, False, (), argparse.SUPPRESS):
        return ""
    if isinstance(action, argparse._StoreTrueAction | argparse._VersionAction):
        return ""
    return f"`{action.default}`"


def _options_table(parser: argparse.ArgumentParser) -> list[str]:
    rows = ["| argument | default | meaning |", "|---|---|---|"]
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
            continue
        if action.option_strings:
            names = ", ".join(f"`{name}`" for name in action.option_strings)
            if action.nargs != 0:
                metavar = action.metavar or action.dest.upper()
                names += f" `{metavar}`"
        else:
            names = f"`{action.metavar or action.dest}`"
        required = " (required)" if action.required and action.option_strings else ""
        rows.append(f"| {names}{required} | {_default(action)} | {_cell(action.help or '')} |")
    return rows


#: Usage lines wrap at this width whatever the terminal, so the page is the same
#: everywhere.
WIDTH = 100


def _fixed_width(prog: str) -> argparse.HelpFormatter:
    return argparse.HelpFormatter(prog, width=WIDTH)


def reference_markdown() -> str:
    """The whole reference page, one section per command, in the parser's order."""
    parser = build_parser()
    parser.formatter_class = _fixed_width
    for command in _subparsers(parser).values():
        command.formatter_class = _fixed_width
    summaries = _summaries(parser)
    lines = [_HEADER, "## pipemap", "", "```", parser.format_usage().strip(), "```", ""]
    lines += _options_table(parser)
    lines.append("")
    for name, command in _subparsers(parser).items():
        lines += [f"## pipemap {name}", "", _cell(summaries.get(name, "")) + ".", ""]
        if command.description:
            lines += [_cell(command.description), ""]
        usage = command.format_usage().strip().removeprefix("usage: ")
        lines += ["```", usage, "```", ""]
        lines += _options_table(command)
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


if __name__ == "__main__":
    sys.stdout.write(reference_markdown())
