"""A replay takes the settings its log was recorded with (``pipemap.run``): the
threshold, which chose the probes the robot made and the online decisions, unless
``--threshold`` gives another; then one note says the two differ."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from pipemap.recorder import METADATA_RUN, LogWriter, read_log

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


def pipemap(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args], capture_output=True, text=True, timeout=300
    )


@pytest.fixture(scope="module")
def at_06(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The stored autonomous run, its settings saying it was recorded at 0.6."""
    contents = read_log(RECORDINGS / "paper_autonomous.mcap")
    run = {**contents.metadata[METADATA_RUN], "threshold": "0.6"}
    path = tmp_path_factory.mktemp("recorded") / "at06.mcap"
    with path.open("wb") as f, LogWriter(f, run) as writer:
        for m in contents.messages:
            writer.write_serialized(m.topic, m.log_time_ns, m.data)
    return path


def _notes(stderr: str) -> list[str]:
    return [line for line in stderr.splitlines() if "though recorded at" in line]


def test_score_takes_the_recorded_threshold(at_06: Path) -> None:
    done = pipemap("score", str(at_06), "--json")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["threshold"] == 0.6
    assert _notes(done.stderr) == []
    # Given explicitly, the threshold is the flag's, and one line says so.
    done = pipemap("score", str(at_06), "--json", "--threshold", "0.36")
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["threshold"] == 0.36
    assert _notes(done.stderr) == [
        f"pipemap: note: {at_06}: replayed at threshold 0.36, though recorded at 0.6: its "
        "probes were asked for, and its online decisions made, at 0.6"
    ]


def test_replay_takes_the_recorded_threshold(at_06: Path) -> None:
    default = pipemap("replay", str(at_06))
    given = pipemap("replay", str(at_06), "--threshold", "0.6")
    other = pipemap("replay", str(at_06), "--threshold", "0.36")
    for done in (default, given, other):
        assert done.returncode == 0, done.stderr
    # At 0.6 active vision asks for probes this run did not make at 0.36.
    assert default.stdout == given.stdout != other.stdout
    assert _notes(default.stderr) == _notes(given.stderr) == []
    assert len(_notes(other.stderr)) == 1


def test_a_log_at_the_default_threshold_gets_no_note() -> None:
    log = str(RECORDINGS / "paper_autonomous.mcap")
    done = pipemap("score", log, "--json")
    assert done.returncode == 0 and json.loads(done.stdout)["threshold"] == 0.36
    assert _notes(done.stderr) == []
    done = pipemap("score", log, "--json", "--threshold", "0.6")
    assert done.returncode == 0 and json.loads(done.stdout)["threshold"] == 0.6
    assert len(_notes(done.stderr)) == 1


def test_view_takes_the_recorded_threshold(at_06: Path, tmp_path: Path) -> None:
    default = pipemap("view", str(at_06), "--save", str(tmp_path / "default.rrd"))
    other = pipemap(
        "view", str(at_06), "--save", str(tmp_path / "other.rrd"), "--threshold", "0.36"
    )
    for done in (default, other):
        assert done.returncode == 0, done.stderr
    assert _notes(default.stderr) == []
    assert len(_notes(other.stderr)) == 1


def test_a_script_takes_the_recorded_threshold_as_the_command_does(at_06: Path) -> None:
    """``api.replay(log)`` and ``api.score(log)`` build what ``pipemap replay LOG`` and
    ``pipemap score LOG`` build: the recorded threshold, unless settings are given."""
    from pipemap import api
    from pipemap.localizer import LocalizerConfig

    assert api.score(at_06).threshold == 0.6
    assert api.score(at_06, LocalizerConfig()).threshold == 0.36
    assert api.score(at_06, LocalizerConfig(), recorded_threshold=True).threshold == 0.6
    by_script = api.replay(at_06).document()
    by_command = json.loads(pipemap("replay", str(at_06)).stdout)
    assert by_script == by_command
    assert api.replay(at_06, LocalizerConfig()).document() != by_script
