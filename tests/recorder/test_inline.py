"""The log written in the recording process (``recorder.inline``): the same bytes as
the writer process's, the same handling of a failed write and of a failed run."""

from __future__ import annotations

from pathlib import Path

import cv2
import pytest

from pipemap import __version__
from pipemap.errors import InputError, WriteError
from pipemap.recorder import Integrity, RecordSettings, read_log, record_run, session
from pipemap.recorder.inline import InlineWriter
from pipemap.recorder.topics import METADATA_RESULT
from pipemap.sim.network import build_network


def no_writer_process(*args: object, **kwargs: object) -> None:
    raise AssertionError("a writer process was started")


@pytest.mark.parametrize("one_thread", [False, True])
def test_inline_writes_the_bytes_of_the_writer_process(
    recorded_run: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, one_thread: bool
) -> None:
    """Also with OpenCV held to one thread, as a batch's task holds it."""
    # recorded_run is `pipemap record` with tests.logs.SMALL_RUN: paper, 64 px, seed 3,
    # its log written by a writer process.
    monkeypatch.setattr(session, "BackgroundWriter", no_writer_process)
    path = tmp_path / "inline.mcap"
    settings = RecordSettings("paper", seed=3, resolution_px=64)
    threads = cv2.getNumThreads()
    # OpenCV's default pool (an earlier test of this worker may have held it to one
    # thread, as a batch's task and the benchmarks do).
    cv2.setNumThreads(-1)
    if one_thread:
        assert cv2.getNumThreads() > 1  # else the case shows nothing
        cv2.setNumThreads(1)
    try:
        network = build_network("paper", seed=3)
        result = record_run(path, settings, network, __version__, inline=True)
    finally:
        cv2.setNumThreads(threads)
    assert result.ok
    assert path.read_bytes() == recorded_run.read_bytes()
    assert result.messages == len(read_log(path).messages)


def test_inline_refuses_an_existing_log_before_writing(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    path.write_bytes(b"keep me")
    with pytest.raises(InputError, match="cannot write the log: .*run.mcap: File exists"):
        InlineWriter(path, "xb", {"pipemap_version": "test"})
    assert path.read_bytes() == b"keep me"


def test_a_full_disk_is_a_write_error_naming_the_file() -> None:
    settings = RecordSettings("paper", seed=3, resolution_px=64)
    with pytest.raises(WriteError, match="writing /dev/full failed: No space left on device"):
        record_run(
            Path("/dev/full"), settings, build_network("paper"), "test", overwrite=True, inline=True
        )


def test_a_run_that_fails_leaves_a_finished_log_that_says_so(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    with (
        pytest.raises(RuntimeError, match="the robot fell"),
        InlineWriter(path, "xb", {"pipemap_version": "test"}),
    ):
        raise RuntimeError("the robot fell")
    contents = read_log(path)
    assert contents.integrity is Integrity.OK
    result = contents.metadata[METADATA_RESULT]
    assert result["status"] == "failed" and "the robot fell" in result["error"]


def test_a_batch_run_writes_its_log_inline(monkeypatch: pytest.MonkeyPatch) -> None:
    from pipemap.batch.run import run_recording
    from pipemap.batch.spec import parse_spec

    monkeypatch.setattr(session, "BackgroundWriter", no_writer_process)
    spec = parse_spec(
        "[grid]\nnetwork = ['paper']\ncondition = ['perfect']\nresolution = [32]\n", "t.toml"
    )
    outcome = run_recording(spec.points[:1])
    assert outcome["record"]["run_ok"]
