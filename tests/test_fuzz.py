"""Random damage to a real log and to an image set: every command either does its job
(exit 0, warnings one line each) or says what is wrong in one line (exit 1, 2 or 3);
never a traceback, never a hang.

The damage: truncations, byte flips and edits of a record's length field (the MCAP
framing), one to three at a time. The commands run in this process (through
``pipemap.cli.main``, as the console script runs them) so that a hundred cases fit
in well under a minute; each call has a time limit, and what the C libraries print
on the process's own standard error is captured too. The examples are derandomized:
CI runs the same cases every time.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal
import struct
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pipemap.cli import main

#: Seconds one command may take on a 32 px log before it counts as a hang.
CALL_LIMIT_S = 30
_FUZZ = settings(
    derandomize="PIPEMAP_FUZZ_RANDOM" not in os.environ,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
_HEAD = struct.Struct("<BQ")
#: Examples per test (times 3 for the log commands, times 2 for image sets, a quarter
#: for the view): 40 keeps the tests under 40 s. ``PIPEMAP_FUZZ_EXAMPLES=300
#: PIPEMAP_FUZZ_RANDOM=1`` hunts further, in other cases than CI's (about 6 min).
_EXAMPLES = int(os.environ.get("PIPEMAP_FUZZ_EXAMPLES", "40"))


class Hang(Exception):
    pass


@contextlib.contextmanager
def _time_limit(seconds: float) -> Iterator[None]:
    def expired(signum: int, frame: object) -> None:
        raise Hang(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def run(*argv: str) -> tuple[int, str, str]:
    """``pipemap ARGV`` in this process: exit status, standard output, standard error
    (what Python wrote, and what C code wrote to file descriptor 2)."""
    out, err = io.StringIO(), io.StringIO()
    with tempfile.TemporaryFile() as native:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(native.fileno(), 2)
        try:
            with (
                contextlib.redirect_stdout(out),
                contextlib.redirect_stderr(err),
                _time_limit(CALL_LIMIT_S),
            ):
                status = main(list(argv))
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        native.seek(0)
        c_level = native.read().decode("utf-8", "replace")
    return status, out.getvalue(), err.getvalue() + c_level


def check(status: int, stderr: str, argv: tuple[str, ...]) -> None:
    where = f"pipemap {' '.join(argv)}"
    assert "Traceback" not in stderr, f"{where}:\n{stderr}"
    assert "()" not in stderr and ": )" not in stderr, f"{where}: an empty reason:\n{stderr}"
    lines = stderr.splitlines()
    assert all(line.startswith("pipemap: ") for line in lines), (
        f"{where}: foreign output:\n{stderr}"
    )
    if status == 0:
        return
    assert status in (1, 2, 3), f"{where}: exit {status}\n{stderr}"
    errors = [line for line in lines if line.startswith("pipemap: error:")]
    assert len(errors) == (0 if status == 1 else 1), f"{where}: exit {status}\n{stderr}"
    if status != 1:  # only the error, nothing else
        assert len(lines) == 1, f"{where}: more than one line with exit {status}:\n{stderr}"


# -- damage ------------------------------------------------------------------------------


def record_starts(data: bytes) -> list[int]:
    """Where each top-level record of an MCAP file starts (its opcode byte)."""
    starts, position = [], 8
    while position + _HEAD.size <= len(data) - 8:
        starts.append(position)
        opcode, length = _HEAD.unpack_from(data, position)
        position += _HEAD.size + length
        if opcode == 0x02:  # footer
            break
    return starts


@st.composite
def damage(draw: st.DrawFn, data: bytes, records: list[int]) -> bytes:
    out = bytearray(data)
    for _ in range(draw(st.integers(1, 3))):
        kind = draw(st.sampled_from(["truncate", "flip"] + (["length"] if records else [])))
        if kind == "truncate" and len(out) > 1:
            del out[draw(st.integers(0, len(out) - 1)) :]
        elif kind == "flip" and out:
            position = draw(st.integers(0, len(out) - 1))
            out[position] ^= draw(st.integers(1, 255))
        elif kind == "length":
            start = draw(st.sampled_from(records)) + 1
            if start + 8 <= len(out):
                (length,) = struct.unpack_from("<Q", out, start)
                new = draw(
                    st.one_of(
                        st.integers(0, 2**64 - 1),
                        st.integers(-64, 64).map(lambda d, n=length: max(0, n + d)),
                    )
                )
                struct.pack_into("<Q", out, start, new)
    return bytes(out)


# -- logs --------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def log_bytes(recorded_run: Path) -> tuple[bytes, list[int]]:
    data = recorded_run.read_bytes()
    return data, record_starts(data)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fuzz")


LOG_COMMANDS = (
    ("info",),
    ("info", "--json"),
    ("replay",),
    ("score", "--json"),
    ("view", "--save", "{out}/view.rrd", "--force"),
)


def test_a_damaged_log_gets_a_result_or_one_line(
    log_bytes: tuple[bytes, list[int]], scratch: Path
) -> None:
    data, records = log_bytes

    @settings(_FUZZ, max_examples=_EXAMPLES * 3)
    @given(damaged=damage(data, records), command=st.sampled_from(LOG_COMMANDS[:4]))
    def case(damaged: bytes, command: tuple[str, ...]) -> None:
        log = scratch / "damaged.mcap"
        log.write_bytes(damaged)
        argv = (command[0], str(log), *(a.format(out=scratch) for a in command[1:]))
        status, _, stderr = run(*argv)
        check(status, stderr, argv)

    case()


def test_a_damaged_log_gets_a_view_or_one_line(
    log_bytes: tuple[bytes, list[int]], scratch: Path
) -> None:
    """The view in fewer cases: it imports and writes with rerun (about a second each)."""
    data, records = log_bytes

    @settings(_FUZZ, max_examples=max(1, _EXAMPLES // 4))
    @given(damaged=damage(data, records))
    def case(damaged: bytes) -> None:
        log = scratch / "damaged_view.mcap"
        log.write_bytes(damaged)
        command = LOG_COMMANDS[-1]
        argv = (command[0], str(log), *(a.format(out=scratch) for a in command[1:]))
        status, _, stderr = run(*argv)
        check(status, stderr, argv)

    case()


# -- image sets --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def image_sets(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    rng = np.random.default_rng(1)
    folders = []
    for name in ("a", "b"):
        folder = tmp_path_factory.mktemp(f"set_{name}")
        for i in range(1, 7):
            image = rng.integers(0, 255, (32, 32), np.uint8)
            cv2.imwrite(str(folder / f"camera_image{i}.png"), image)
        folders.append(folder)
    return folders


def test_a_damaged_image_set_gets_a_result_or_one_line(image_sets: list[Path]) -> None:
    target = image_sets[1] / "camera_image4.png"
    original = target.read_bytes()

    @settings(_FUZZ, max_examples=_EXAMPLES * 2)
    @given(damaged=damage(original, []), command=st.sampled_from(["match", "map"]))
    def case(damaged: bytes, command: str) -> None:
        target.write_bytes(damaged)
        argv = (command, *map(str, image_sets))
        status, _, stderr = run(*argv)
        check(status, stderr, argv)

    try:
        case()
    finally:
        target.write_bytes(original)


# -- valid MCAP, broken payloads ---------------------------------------------------------


@pytest.fixture(scope="module")
def slim_log(recorded_run: Path) -> tuple[dict[str, str], dict[str, str], list[object]]:
    """The recorded run's metadata and the messages a score reads (a tenth of them),
    so that a log can be written anew for each case in a fraction of a second."""
    from pipemap.recorder import METADATA_RESULT, METADATA_RUN, read_log
    from pipemap.replay import SCORE_TOPICS

    contents = read_log(recorded_run)
    kept = [m for m in contents.messages if m.topic in SCORE_TOPICS]
    return contents.metadata[METADATA_RUN], contents.metadata[METADATA_RESULT], kept


@st.composite
def broken_payloads(draw: st.DrawFn, messages: list[object]) -> dict[int, bytes]:
    """New payloads for one to three messages of one topic: random bytes, a payload
    cut short, a byte flipped, or nothing."""
    topics = sorted({m.topic for m in messages})  # type: ignore[attr-defined]
    topic = draw(st.sampled_from(topics))
    indexes = [i for i, m in enumerate(messages) if m.topic == topic]  # type: ignore[attr-defined]
    changed = {}
    for index in draw(st.lists(st.sampled_from(indexes), min_size=1, max_size=3, unique=True)):
        data = messages[index].data  # type: ignore[attr-defined]
        kind = draw(st.sampled_from(["garbage", "cut", "flip", "empty"]))
        if kind == "garbage":
            changed[index] = draw(st.binary(min_size=1, max_size=64))
        elif kind == "cut" and len(data) > 1:
            changed[index] = data[: draw(st.integers(1, len(data) - 1))]
        elif kind == "flip" and data:
            flipped = bytearray(data)
            flipped[draw(st.integers(0, len(data) - 1))] ^= draw(st.integers(1, 255))
            changed[index] = bytes(flipped)
        else:
            changed[index] = b""
    return changed


def test_a_log_with_broken_payloads_gets_a_result_or_one_line(
    slim_log: tuple[dict[str, str], dict[str, str], list[object]], scratch: Path
) -> None:
    """Structure-aware: every record of the log is whole MCAP written by pipemap's own
    writer, and one topic's payloads are broken (every topic the replay and the score
    read, /truth included); fewer cases than the byte-level fuzz, each a new log."""
    from pipemap.recorder import LogWriter

    run_metadata, result_metadata, messages = slim_log

    @settings(_FUZZ, max_examples=max(1, _EXAMPLES // 2))
    @given(changed=broken_payloads(messages), command=st.sampled_from(LOG_COMMANDS[:4]))
    def case(changed: dict[int, bytes], command: tuple[str, ...]) -> None:
        log = scratch / "payloads.mcap"
        with log.open("wb") as f, LogWriter(f, run_metadata) as writer:
            for i, m in enumerate(messages):
                data = changed.get(i, m.data)  # type: ignore[attr-defined]
                writer.write_serialized(m.topic, m.log_time_ns, data)  # type: ignore[attr-defined]
            writer.finish(result_metadata)
        argv = (command[0], str(log), *command[1:])
        status, _, stderr = run(*argv)
        check(status, stderr, argv)

    case()
