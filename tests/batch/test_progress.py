"""The batch's progress: one line kept up to date on a terminal (done/total, failures,
time left), one line per finished run otherwise."""

from __future__ import annotations

import io

from pipemap.batch import BatchEvent
from pipemap.batch.spec import RunPoint
from pipemap.cli.batch_command import format_duration, progress_printer

POINT = RunPoint(
    "paper", 0, "S", "perfect", 32, 6, True, "map", 0, 0, 0.0, "lamp", 0.0, 1.0, "default", 0.36
)
OK = {
    "status": "ok",
    "score": {
        "map_correct": True,
        "visits": 13,
        "decisions": {"correct_known": 6, "correct_new": 7, "false_merge": 0, "false_new": 0},
    },
}
FAILED = {"status": "failed", "reason": "RuntimeError: boom"}


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def events() -> list[BatchEvent]:
    return [
        BatchEvent("start", None, None, 0, 4, 0, 0, 0.5),
        BatchEvent("tick", None, None, 0, 4, 0, 2, 1.5),
        BatchEvent("ok", POINT, OK, 1, 4, 0, 1, 30.0),
        BatchEvent("failed", POINT, FAILED, 2, 4, 1, 1, 60.0),
    ]


def test_one_line_per_run_when_not_a_terminal() -> None:
    err = io.StringIO()
    show = progress_printer(err)
    for e in events():
        show(e)
    assert err.getvalue().splitlines() == [
        f"[1/4] {POINT.run_id}: map correct, 13/13 decisions right",
        f"[2/4] {POINT.run_id}: FAILED: RuntimeError: boom",
    ]


def test_a_progress_line_on_a_terminal() -> None:
    err = Terminal()
    show = progress_printer(err)
    for e in events():
        show(e)
    text = err.getvalue()
    assert "\n" not in text.split(f"\n  {POINT.run_id}")[0]  # one line rewritten in place
    screens = text.split("\r")
    assert "0/4 runs done, 0 failed, 2 running" in screens[2]
    assert "estimating time left" in screens[2]
    assert "1/4 runs done, 0 failed" in screens[3] and "1 min 30 s left" in screens[3]
    assert "2/4 runs done, 1 failed" in screens[4] and "1 min 00 s left" in screens[4]
    assert f"\n  {POINT.run_id}: FAILED: RuntimeError: boom\n" in text  # failures stay


def test_durations() -> None:
    assert format_duration(42.4) == "42 s"
    assert format_duration(185) == "3 min 05 s"
    assert format_duration(3725) == "1 h 02 min"
