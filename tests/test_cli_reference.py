"""The command-line reference in ``docs/cli.md`` is the parser's own, flag for flag."""

from __future__ import annotations

import argparse
import re
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


#: The page whose synopsis (its first ``text`` block) lists each command's flags.
SYNOPSIS_PAGES = {
    "sim": "simulator.md",
    "record": "recorder.md",
    "info": "recorder.md",
    "view": "view.md",
    "replay": "replay.md",
    "score": "replay.md",
    "match": "imagesets.md",
    "map": "imagesets.md",
    "route": "imagesets.md",
    "batch": "batch.md",
    "batch-report": "batch.md",
    "experiment": "batch.md",
    "import": "ros2.md",
    "export": "ros2.md",
}


def _synopsis(command: str) -> str:
    """The lines of the command's page synopsis that belong to ``pipemap COMMAND``."""
    page = (PAGE.parent / SYNOPSIS_PAGES[command]).read_text()
    block = page.split("```text\n", 1)[1].split("```", 1)[0]
    lines, mine = [], False
    for line in block.splitlines():
        if line.startswith("pipemap "):
            mine = line.split()[1] == command
        if mine:
            lines.append(line)
    assert lines, f"{SYNOPSIS_PAGES[command]}'s synopsis has no pipemap {command}"
    return "\n".join(lines)


def test_every_command_has_a_synopsis_page() -> None:
    assert set(SYNOPSIS_PAGES) == set(_commands()) - {""}


@pytest.mark.parametrize("command", sorted(SYNOPSIS_PAGES))
def test_the_synopsis_of_a_command_names_every_flag(command: str) -> None:
    """A page's synopsis drifts from the parser when a flag is added: each flag
    (any one of its spellings) must be there."""
    synopsis = _synopsis(command)
    for action in _commands()[command]._actions:
        if isinstance(action, argparse._HelpAction) or not action.option_strings:
            continue
        assert any(
            re.search(re.escape(flag) + r"(?![\w-])", synopsis) for flag in action.option_strings
        ), f"docs/{SYNOPSIS_PAGES[command]}: pipemap {command} lacks {action.option_strings}"


def test_the_batch_description_names_every_grid_key() -> None:
    from pipemap.batch.spec import GRID_KEYS

    description = _commands()["batch"].description or ""
    missing = [key for key in GRID_KEYS if not re.search(rf"\b{key}\b", description)]
    assert not missing, f"pipemap batch --help does not name the grid keys {missing}"


def test_the_sim_description_names_its_default_condition() -> None:
    """sim's default condition is placed, so its description must say the tour is the
    paper's right-most-branch one there, and that --explore is the autonomous run's."""
    sim = _commands()["sim"]
    condition = next(a for a in sim._actions if "--condition" in a.option_strings)
    description = sim.description or ""
    assert f"{condition.default}, the default" in description
    assert "right-most-branch tour" in description and "--explore" in description
