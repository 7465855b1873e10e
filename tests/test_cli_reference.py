"""The command-line reference in ``docs/cli.md`` is the parser's own, flag for flag."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest

from pipemap.cli.parser import build_parser
from pipemap.cli.reference import reference_markdown

PAGE = Path(__file__).resolve().parents[1] / "docs" / "cli.md"


def _commands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return {"": parser, **sub.choices}


def test_the_page_is_what_the_parser_generates() -> None:
    assert PAGE.read_text() == reference_markdown(), (
        "docs/cli.md is stale: run python -m pipemap.cli.reference > docs/cli.md"
    )


@pytest.mark.parametrize("command", sorted(_commands()))
def test_every_flag_is_documented_with_its_help(command: str) -> None:
    page = PAGE.read_text()
    heading = f"## pipemap {command}".rstrip()
    assert f"\n{heading}\n" in page, heading
    section = page.split(f"\n{heading}\n", 1)[1].split("\n## ", 1)[0]
    for action in _commands()[command]._actions:
        if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
            continue
        assert action.help, f"{command}: {action.option_strings or action.dest} has no help"
        for flag in action.option_strings:
            assert f"`{flag}`" in section, f"pipemap {command} {flag} is not in docs/cli.md"


def test_the_check_catches_an_undocumented_flag(monkeypatch: pytest.MonkeyPatch) -> None:
    """The comparison is not vacuous: a flag the page does not have makes it fail."""
    import pipemap.cli.reference as reference

    def with_extra_flag() -> argparse.ArgumentParser:
        parser = build_parser()
        parser.add_argument("--not-in-the-manual", action="store_true", help="new")
        return parser

    monkeypatch.setattr(reference, "build_parser", with_extra_flag)
    generated = reference.reference_markdown()
    assert "`--not-in-the-manual`" in generated
    assert generated != PAGE.read_text()


def _test_sources() -> str:
    here = Path(__file__).resolve()
    return "\n".join(
        p.read_text() for p in sorted(PAGE.parents[1].glob("tests/**/*.py")) if p != here
    )


def _unexercised(parser_of: dict[str, argparse.ArgumentParser], sources: str) -> list[str]:
    """``command flag`` of every flag no test source passes (in any of its spellings)."""
    missing = []
    for command, parser in sorted(parser_of.items()):
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
                continue
            spellings = action.option_strings
            if spellings and not any(f'"{flag}"' in sources for flag in spellings):
                missing.append(f"{command} {spellings[-1]}".strip())
    return missing


def test_every_flag_is_passed_by_some_test() -> None:
    """A tripwire, not the proof: a flag no test even passes cannot have a test that
    fails when the command ignores it. (Each flag's own test is named in the
    CHANGELOG; they were found by making the command line drop one flag at a time.)"""
    assert _unexercised(_commands(), _test_sources()) == []


def test_the_tripwire_catches_a_flag_no_test_passes() -> None:
    parser = build_parser()
    parser.add_argument("--never-passed", action="store_true", help="new")
    assert _unexercised({"": parser}, _test_sources()) == ["--never-passed"]
