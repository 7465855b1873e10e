"""How the command line meets a user: bare ``pipemap`` shows what there is, ``-v`` goes
before or after the command, ``--help`` gives each flag's valid range, a flag the
chosen condition ignores or a value beyond the image is refused in one line, and a
slow world build says so on stderr."""

from __future__ import annotations

import argparse
import io
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from pipemap.cli import slow
from pipemap.cli.parser import build_parser
from tests.batch.test_spec import cli
from tests.cli.common import ROOT, run_subprocess

LOG = ROOT / "recordings" / "paper_autonomous.mcap"


def test_bare_pipemap_prints_its_usage_and_exits_2() -> None:
    code, lines = cli()
    assert code == 2
    assert lines[0].startswith("usage: pipemap")
    text = "\n".join(lines)
    for command in ("record", "score", "batch", "info"):
        assert f"    {command} " in text
    assert lines[-1] == "pipemap: error: a command is required"


def _debug_lines(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("pipemap: DEBUG:")]


def test_verbose_works_after_the_command_too(tmp_path: Path) -> None:
    before = run_subprocess(["-v", "score", str(LOG), "--json"], tmp_path)
    after = run_subprocess(["score", str(LOG), "--json", "-v"], tmp_path)
    assert before.returncode == after.returncode == 0, after.stderr
    assert len(_debug_lines(after.stderr)) == 13  # every visit's decision
    # The same decisions (each line ends with its time, which varies).
    assert [x.rsplit(";", 1)[0] for x in _debug_lines(after.stderr)] == [
        x.rsplit(";", 1)[0] for x in _debug_lines(before.stderr)
    ]


def test_verbose_after_the_command_keeps_one_given_before() -> None:
    parser = build_parser()
    assert parser.parse_args(["-v", "score", "x"]).verbose is True
    assert parser.parse_args(["score", "x", "-v"]).verbose is True
    assert parser.parse_args(["score", "x"]).verbose is False
    assert parser.parse_args(["-v", "map", "a"]).verbose is True


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (action,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


def test_help_shows_the_range_of_every_checked_flag() -> None:
    ranged = 0
    for name, parser in _subparsers(build_parser()).items():
        text = " ".join(parser.format_help().split())  # wrapping undone
        for action in parser._actions:
            span = getattr(action.type, "span", None)
            if span is not None:
                ranged += 1
                assert f"[{span}]" in text, (name, action.option_strings)
    assert ranged >= 20
    record = " ".join(_subparsers(build_parser())["record"].format_help().split())
    for span in ("[16..4096 px]", "[2..72]", "[0..15 degrees]", "[-1..1]"):
        assert span in record


@pytest.mark.parametrize(
    ("command", "flags", "message"),
    [
        ("sim", ["--explore", "right-hand"], "--explore right-hand: only the autonomous robot"),
        ("record", ["--explore", "map", "--condition", "noise"], "--explore map: only the"),
        ("sim", ["--obstacles", "2"], "--obstacles: only the autonomous robot"),
        ("record", ["--motor-faults", "1", "--condition", "active"], "--motor-faults: only"),
    ],
    ids=["sim-explore", "record-explore", "sim-obstacles", "record-motor-faults"],
)
def test_a_flag_the_condition_ignores_is_refused(
    tmp_path: Path, command: str, flags: list[str], message: str
) -> None:
    out = tmp_path / "out"
    target = ["--save-sweeps", str(out)] if command == "sim" else ["-o", str(out)]
    code, lines = cli(command, "--network", "paper", *flags, *target)
    assert code == 2 and len(lines) == 1 and message in lines[0], lines
    assert not out.exists()


def test_a_downsampling_beyond_every_image_is_refused_by_the_parser() -> None:
    code, lines = cli("score", str(LOG), "--downsample", "100000")
    assert code == 2 and len(lines) == 1 and "--downsample" in lines[0], lines


def test_a_downsampling_beyond_the_logs_images_is_refused(tmp_path: Path) -> None:
    done = run_subprocess(["replay", str(LOG), "--downsample", "1000"], tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "downsampling by 1000" in done.stderr
    assert "at most" in done.stderr and done.stdout == ""


def test_a_downsampling_beyond_the_logs_images_is_refused_before_any_sweep(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # The log's settings give its images' size: the replay stops at its first message,
    # before it has read, let alone prepared, a sweep.
    from pipemap import api
    from pipemap.errors import InputError
    from pipemap.localizer import FastConfig, LocalizerConfig
    from pipemap.recorder import Topic
    from pipemap.replay import SCORE_TOPICS, StreamSource

    source = StreamSource(LOG, SCORE_TOPICS)
    read: list[object] = []
    stream = source.robot_stream

    def counted() -> Iterator[object]:
        for m in stream():
            read.append(m)
            yield m

    monkeypatch.setattr(source, "robot_stream", counted)
    config = LocalizerConfig(fast=FastConfig(fine_downsample=1000))
    with pytest.raises(InputError, match=r"downsampling by 1000 .* at most "):
        api.score(source, config)
    # Only the few the replay's reordering window holds: not one sweep's images.
    images = [m for m in read if getattr(m, "topic", None) == Topic.IMAGE]
    assert 1 <= len(read) <= 8 and len(images) < 6


class Terminal(io.StringIO):
    """Standard error as a terminal: where progress lines are shown."""

    def isatty(self) -> bool:
        return True


def test_a_slow_step_says_so_and_how_long_it_took(monkeypatch: pytest.MonkeyPatch) -> None:
    err = Terminal()
    monkeypatch.setattr(slow, "SLOW_S", 0.05)
    with slow.SlowNotice(err, "building the world of x", "world built"):
        time.sleep(0.3)
    lines = err.getvalue().splitlines()
    assert lines[0] == "pipemap: building the world of x ..."
    assert lines[1].startswith("pipemap: world built in ") and lines[1].endswith(" s")
    quick = Terminal()
    with slow.SlowNotice(quick, "building", "built"):
        pass
    time.sleep(0.1)
    assert quick.getvalue() == ""
    piped = io.StringIO()  # not a terminal: stderr keeps to warnings and errors
    with slow.SlowNotice(piped, "building", "built"):
        time.sleep(0.3)
    assert piped.getvalue() == ""


ACTIVE = ROOT / "recordings" / "paper_active.mcap"


def test_score_takes_several_logs(tmp_path: Path) -> None:
    import json

    both = run_subprocess(["score", str(LOG), str(ACTIVE), "--json"], tmp_path)
    assert both.returncode == 0, both.stderr
    reports = json.loads(both.stdout)
    assert isinstance(reports, list) and len(reports) == 2
    for report, log in zip(reports, (LOG, ACTIVE), strict=True):
        stored = json.loads(log.with_suffix("").with_suffix(".score.json").read_text())
        assert report["decisions"] == stored["decisions"]
        assert report["map_correct"] is stored["map_correct"] is True
    text = run_subprocess(["score", str(LOG), str(ACTIVE)], tmp_path)
    assert text.returncode == 0, text.stderr
    logs = [line for line in text.stdout.splitlines() if line.startswith("log ")]
    assert [line.split()[1] for line in logs] == [str(LOG), str(ACTIVE)]


def test_score_checks_every_log_before_the_first_replay(tmp_path: Path) -> None:
    missing = tmp_path / "none.mcap"
    code, lines = cli("score", str(LOG), str(missing))
    assert code == 2 and lines == [f"pipemap: error: {missing}: no such file"], lines
    code, lines = cli("score", str(LOG), str(ACTIVE), "--save-results", str(tmp_path / "s"))
    assert code == 2 and len(lines) == 1 and "one log" in lines[0], lines
    assert not (tmp_path / "s").exists()
