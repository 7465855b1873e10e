"""``pipemap record`` on a terminal: a world slow to build says how far it has come."""

from __future__ import annotations

import io

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
    show = log_commands._progress_printer(err)
    assert show is not None
    show(Progress(0, 0, 0, world_pieces=(0, 50)))  # starts the clock at 100 s
    show(Progress(0, 0, 0, world_pieces=(1, 50)))  # 0.5 s: quiet
    assert err.getvalue() == ""
    show(Progress(0, 0, 0, world_pieces=(30, 50)))  # 3 s: slow, shown
    assert err.getvalue().endswith("building the world: 30/50 pipes and nodes ")
    show(Progress(2_000_000_000, 1, 1))
    assert "recording:" in err.getvalue().rsplit("\r", 1)[1]


def test_no_progress_line_off_a_terminal() -> None:
    assert log_commands._progress_printer(io.StringIO()) is None
