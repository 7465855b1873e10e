"""Stopping a batch's driver: Ctrl-C and SIGTERM wait while a recording's runs are
written, so an interrupted batch keeps all of a recording's runs or none (the runs
share one log, which ``--resume`` would otherwise record again for the rest)."""

from __future__ import annotations

import signal
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from pipemap.batch import results
from pipemap.batch.signals import held_signals, terminate_as_interrupt
from pipemap.batch.spec import RunPoint

POINT = RunPoint(
    "paper", 0, "S", "perfect", 32, 6, True, "map", 0, 0, 0.0, "lamp", 0.0, 1.0, "default", 0.36
)
#: The two rules of one recording.
POINTS = (POINT, replace(POINT, rule="paper"))


def test_ctrl_c_in_the_block_takes_effect_when_it_ends() -> None:
    before = signal.getsignal(signal.SIGINT)
    done = []
    with pytest.raises(KeyboardInterrupt), held_signals():
        signal.raise_signal(signal.SIGINT)
        done.append("the rest of the block")
    assert done == ["the rest of the block"]
    assert signal.getsignal(signal.SIGINT) is before


def test_sigterm_in_the_block_stops_as_ctrl_c_when_it_ends() -> None:
    done = []
    with terminate_as_interrupt():
        with pytest.raises(KeyboardInterrupt), held_signals():
            signal.raise_signal(signal.SIGTERM)
            done.append("the rest of the block")
        # A second stop is ignored until the table is written (terminate_as_interrupt).
        assert signal.getsignal(signal.SIGTERM) is signal.SIG_IGN
    assert done == ["the rest of the block"]


def test_a_block_without_a_stop_leaves_the_handlers_as_they_were() -> None:
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    with held_signals():
        pass
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


@pytest.mark.parametrize("outcome", [{"runs": {}}, None], ids=["scored", "failed"])
def test_ctrl_c_while_a_recording_is_written_waits_for_all_its_runs(
    outcome: dict[str, Any] | None, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C arrives as the first rule's run is written: the second is written too,
    then the batch stops."""
    written: list[str] = []

    def write(out: Path, point: RunPoint, *args: Any) -> dict[str, Any]:
        if not written:
            signal.raise_signal(signal.SIGINT)
        written.append(point.run_id)
        return {"status": "ok" if outcome is not None else "failed"}

    monkeypatch.setattr(results, "write_run", write)
    monkeypatch.setattr(results, "write_failed", write)
    with pytest.raises(KeyboardInterrupt):
        results.write_recording(tmp_path, POINTS, outcome, "boom", keep_log=True)
    assert written == [p.run_id for p in POINTS]


def test_ctrl_c_while_a_recording_is_written_leaves_it_whole_in_the_table(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The driver counts a finished recording's runs in the table's rows in the same
    step as it writes their folders: the table a stop writes holds every run whose
    folder is written (the stop once left both runs' folders and neither row)."""
    from pipemap.batch import engine

    def write(out: Path, point: RunPoint, *args: Any) -> dict[str, Any]:
        if point is POINTS[0]:
            signal.raise_signal(signal.SIGINT)
        return {"status": "ok", "run_id": point.run_id}

    monkeypatch.setattr(results, "write_run", write)
    monkeypatch.setattr(engine, "result_row", lambda out, doc: {"run_id": doc["run_id"]})
    summary = engine.BatchSummary(total=2, skipped=0)
    rows: dict[str, dict[str, Any]] = {}
    events: list[str] = []
    with pytest.raises(KeyboardInterrupt):
        engine._take_recording(
            tmp_path,
            POINTS,
            {"cpu_s": 1.5},
            "",
            True,
            summary,
            rows,
            lambda k, p, d: events.append(k),
        )
    assert list(rows) == [p.run_id for p in POINTS]
    assert (summary.done, summary.failed, summary.cpu_s, events) == (2, 0, 1.5, ["ok", "ok"])
