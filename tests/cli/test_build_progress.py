"""``pipemap record`` on a terminal: a world slow to build says how far it has come."""

from __future__ import annotations

import io
import sys
from pathlib import Path

import pytest

from pipemap.cli import log_commands
from pipemap.recorder.session import Progress


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_build_line_shows_only_once_the_build_is_slow(monkeypatch: pytest.MonkeyPatch) -> None:
    clock = iter([100.0, 100.0, 100.5, 103.0])
    monkeypatch.setattr(log_commands.time, "monotonic", lambda: next(clock))
    err = _Terminal()
    show = log_commands.progress_printer(err)
    assert show is not None
    show(Progress(0, 0, 0, world_pieces=(0, 50)))  # starts the clock at 100 s
    show(Progress(0, 0, 0, world_pieces=(1, 50)))  # 0.5 s: quiet
    assert err.getvalue() == ""
    show(Progress(0, 0, 0, world_pieces=(30, 50)))  # 3 s: slow, shown
    assert err.getvalue().endswith("building the world: 30/50 pipes and nodes ")
    show(Progress(2_000_000_000, 1, 1))
    assert "recording:" in err.getvalue().rsplit("\r", 1)[1]


def test_no_progress_line_off_a_terminal() -> None:
    assert log_commands.progress_printer(io.StringIO()) is None


@pytest.mark.parametrize(
    "command,output,doing",
    [("record", "-o", "recording"), ("sim", "--save-sweeps", "simulating")],
)
def test_a_streamed_world_has_no_build_line_through_the_command(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, command: str, output: str, doing: str
) -> None:
    """The command on a terminal: the world is streamed (each piece built when first
    seen), so even with no quiet time there is no world build to report, only the run
    saying how far it has come."""
    from pipemap.cli import main

    monkeypatch.setattr(log_commands, "_QUIET_BUILD_S", 0.0)
    err = _Terminal()
    monkeypatch.setattr(sys, "stderr", err)
    argv = [command, "--network", "tree:2", "--condition", "perfect", "--resolution", "16"]
    assert main([*argv, output, str(tmp_path / "out")]) == 0, err.getvalue()
    lines = err.getvalue().split("\r")
    assert not [line for line in lines if line.startswith("building the world: ")]
    assert any(line.startswith(f"{doing}: ") for line in lines)
