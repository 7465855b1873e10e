"""The fault table of ``docs/faults.md``: each case, the command's exit status and
one clear line, and what is kept. Rows tested elsewhere name their test there;
``test_every_row_of_the_fault_table_names_a_test_that_exists`` keeps the two in step.
"""

from __future__ import annotations

import ast
import json
import re
import resource
import stat
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipemap.recorder import METADATA_RESULT, METADATA_RUN, LogWriter, Topic, read_log, schemas
from tests.logs import sweeps_started

REPO = Path(__file__).resolve().parents[1]
STORED = REPO / "recordings" / "paper_autonomous.mcap"


def pipemap(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args], capture_output=True, text=True, timeout=timeout
    )


def assert_one_line(done: subprocess.CompletedProcess[str], status: int, *texts: str) -> None:
    """Exit ``status`` and one line on standard error holding every one of ``texts``."""
    assert done.returncode == status, done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr, done.stderr
    for text in texts:
        assert text in done.stderr


def rewrite(source: Path, target: Path, change: Callable[[int, object], bytes | None]) -> None:
    """Copy a log message by message with pipemap's writer; ``change(i, message)`` gives
    new bytes for message ``i`` (``None`` keeps it); a ``StopIteration`` ends the copy
    there (a log interrupted at that point, closed properly)."""
    contents = read_log(source)
    with target.open("wb") as f, LogWriter(f, contents.metadata[METADATA_RUN]) as writer:
        for i, m in enumerate(contents.messages):
            try:
                data = change(i, m)
            except StopIteration:
                break
            writer.write_serialized(m.topic, m.log_time_ns, m.data if data is None else data)
        writer.finish(contents.metadata[METADATA_RESULT])


def nth_image(n: int) -> Callable[[Path], int]:
    """The index among a log's messages of its ``n``-th image (0-based)."""

    def find(log: Path) -> int:
        images = [i for i, m in enumerate(read_log(log).messages) if m.topic == Topic.IMAGE]
        return images[n]

    return find


# -- logs cut short ----------------------------------------------------------------------


def _first_chunk_end(data: bytes) -> int:
    position = 8 + 9 + int.from_bytes(data[9:17], "little")
    while data[position] != 0x06:
        position += 9 + int.from_bytes(data[position + 1 : position + 9], "little")
    return position + 9 + int.from_bytes(data[position + 1 : position + 9], "little")


def test_a_log_cut_before_its_first_complete_sweep_replays_to_an_empty_map(
    recorded_run: Path, tmp_path: Path
) -> None:
    data = recorded_run.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: _first_chunk_end(data) // 2])  # inside the first sweep's chunk
    for command in ("replay", "score"):
        done = pipemap(command, str(cut), *(["--json"] if command == "score" else []))
        assert done.returncode == 0, done.stderr
        assert "Traceback" not in done.stderr and "is cut short" in done.stderr
        assert json.loads(done.stdout)["visits"] in ([], 0)
    info = pipemap("info", "--json", str(cut))
    assert info.returncode == 0 and json.loads(info.stdout)["integrity"] == "truncated"


def test_a_log_cut_before_its_run_metadata_is_one_line(recorded_run: Path, tmp_path: Path) -> None:
    data = recorded_run.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[:40])  # the header, and a few bytes of the metadata record
    for command in ("info", "replay"):
        assert_one_line(pipemap(command, str(cut)), 2, "cut short before its pipemap.run metadata")


def test_info_counts_only_the_sweeps_a_replay_keeps(recorded_run: Path, tmp_path: Path) -> None:
    """A log interrupted in the middle of its third sweep: two sweeps, not three."""
    commands = [
        (i, schemas.SweepCommand.FromString(m.data))
        for i, m in enumerate(read_log(recorded_run).messages)
        if m.topic == Topic.SWEEP
    ]
    stop = [i for i, c in commands if c.sweep_id == 3 and c.phase == c.IMAGE][2]

    def cut(i: int, _m: object) -> None:
        if i == stop:
            raise StopIteration

    interrupted = tmp_path / "interrupted.mcap"
    rewrite(recorded_run, interrupted, cut)
    doc = json.loads(pipemap("info", "--json", str(interrupted)).stdout)
    assert doc["sweeps"] == 2 and len(doc["sweeps_skipped"]) == 1
    assert "sweep 3 of visit 3 was cut off" in doc["sweeps_skipped"][0]
    replayed = pipemap("replay", str(interrupted))
    assert replayed.returncode == 0 and len(json.loads(replayed.stdout)["visits"]) == 2


# -- messages that cannot be read -------------------------------------------------------

BAD_IMAGES = {
    "empty": (b"", "image 2 of 6", "is in format '', not png"),
    "not-protobuf": (b"\x0a\xff\xff\x03abc", "image 2 of 6", "does not decode"),
    "not-png": (
        schemas.CompressedImage(
            format="png", data=b"\x89PNG\r\n\x1a\nnot an image"
        ).SerializeToString(),
        "image 2 of 6",
        "is not a readable PNG",
    ),
    "cut-jpeg": (
        schemas.CompressedImage(
            format="jpeg", data=b"\xff\xd8\xff\xe0 cut short"
        ).SerializeToString(),
        "image 2 of 6",
        "is not a readable JPEG",
    ),
}


@pytest.fixture(scope="module", params=sorted(BAD_IMAGES))
def bad_image_log(
    request: pytest.FixtureRequest, recorded_run: Path, tmp_path_factory: pytest.TempPathFactory
) -> tuple[Path, str]:
    """The recorded run's first four sweeps, the second image of the third replaced.
    (The rest of the run would only make each replay, score, view and info longer: the
    sweeps after the bad one are read as the fourth is.)"""
    payload, *_ = BAD_IMAGES[request.param]
    target = nth_image(2 * 6 + 1)(recorded_run)
    end = _sweep_start(recorded_run, 5)
    path = tmp_path_factory.mktemp("bad_image") / f"{request.param}.mcap"

    def change(i: int, _m: object) -> bytes | None:
        if i == end:
            raise StopIteration
        return payload if i == target else None

    rewrite(recorded_run, path, change)
    return path, request.param


def _sweep_start(log: Path, sweep_id: int) -> int:
    """The index among a log's messages of the command that starts sweep ``sweep_id``."""
    for i, m in enumerate(read_log(log).messages):
        if m.topic == Topic.SWEEP:
            command = schemas.SweepCommand.FromString(m.data)
            if command.sweep_id == sweep_id and command.phase == command.START:
                return i
    raise AssertionError(f"{log} has no sweep {sweep_id}")


def test_an_unreadable_image_in_a_log_loses_its_sweep_only(
    bad_image_log: tuple[Path, str], tmp_path: Path
) -> None:
    path, kind = bad_image_log
    _, which, why = BAD_IMAGES[kind]
    replayed = pipemap("replay", str(path))
    assert replayed.returncode == 0, replayed.stderr
    notes = [line for line in replayed.stderr.splitlines() if "skipped" in line]
    assert len(notes) == 1 and "sweep 3 of visit 3 skipped" in notes[0]
    assert which in notes[0] and why in notes[0]
    assert "Traceback" not in replayed.stderr and "libpng" not in replayed.stderr
    visits = json.loads(replayed.stdout)["visits"]
    sweeps = sweeps_started(path)  # one a visit (four): the third one's is lost
    assert sweeps == 4
    assert [v["set"] for v in visits] == [f"{i:04d}" for i in range(1, sweeps + 1) if i != 3]
    scored = pipemap("score", "--json", str(path))
    assert scored.returncode == 0 and json.loads(scored.stdout)["visits"] == sweeps - 1
    viewed = pipemap("view", str(path), "--save", str(tmp_path / "v.rrd"))
    assert viewed.returncode == 0 and "Traceback" not in viewed.stderr, viewed.stderr
    info = pipemap("info", "--json", str(path))
    doc = json.loads(info.stdout)
    assert doc["sweeps"] == sweeps - 1
    if kind == "not-protobuf":  # info decodes every message: it is damage
        assert info.returncode == 1 and doc["undecodable"] == {Topic.IMAGE: 1}
    else:  # a well-formed message whose image is no PNG: a replay skips it, info says so
        assert info.returncode == 0 and len(doc["sweeps_skipped"]) == 1


def test_an_exit_scan_that_does_not_decode_loses_that_visits_ports_only(
    tmp_path: Path,
) -> None:
    contents = read_log(STORED)
    scans = [
        i
        for i, m in enumerate(contents.messages)
        if m.topic == Topic.NODE
        and schemas.NodeEvent.FromString(m.data).kind == schemas.NodeEvent.EXITS
    ]
    broken = tmp_path / "bad_scan.mcap"
    rewrite(STORED, broken, lambda i, _m: b"\x0a\xff\xff\xff\x0f" if i == scans[2] else None)
    done = pipemap("replay", str(broken))
    assert done.returncode == 0, done.stderr
    # One line for the lost scan (the lamp-lit log's probe note may stand beside it).
    lines = [line for line in done.stderr.splitlines() if "node event" in line]
    assert len(lines) == 1 and "Traceback" not in done.stderr
    assert "1 node event(s) do not decode as pipemap.NodeEvent" in lines[0]
    visits = json.loads(done.stdout)["visits"]
    assert len(visits) == 13  # every visit is decided, the third without its exits
    assert visits[2]["exits_rad"] is None and visits[1]["exits_rad"] is not None


def test_a_log_whose_messages_are_not_protobuf_is_read_without_a_traceback(
    recorded_run: Path, tmp_path: Path
) -> None:
    garbage = tmp_path / "garbage.mcap"
    rewrite(recorded_run, garbage, lambda _i, _m: b"\x0a\xff\xff\xff\x0f")
    info = pipemap("info", str(garbage))
    assert info.returncode == 1 and "Traceback" not in info.stderr
    assert "integrity  corrupt" in info.stdout and "do not decode" in info.stdout
    replayed = pipemap("replay", str(garbage))
    assert replayed.returncode == 0 and "Traceback" not in replayed.stderr
    assert json.loads(replayed.stdout)["visits"] == []
    assert "camera command(s) do not decode" in replayed.stderr


# -- image sets --------------------------------------------------------------------------


@pytest.fixture
def image_set(tmp_path: Path) -> Path:
    folder = tmp_path / "set"
    folder.mkdir()
    rng = np.random.default_rng(0)
    for i in range(1, 7):
        cv2.imwrite(str(folder / f"camera_image{i}.png"), rng.integers(0, 255, (24, 32), np.uint8))
    return folder


@pytest.mark.parametrize("command", ["match", "map"])
def test_an_empty_image_in_an_image_set_is_one_line(image_set: Path, command: str) -> None:
    (image_set / "camera_image2.png").write_bytes(b"")
    done = pipemap(command, str(image_set), str(image_set))
    assert_one_line(done, 2, "camera_image2.png: empty file, not an image")


@pytest.mark.parametrize("command", ["match", "map"])
def test_a_damaged_png_in_an_image_set_is_one_line_and_no_libpng(
    image_set: Path, command: str
) -> None:
    path = image_set / "camera_image3.png"
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x55
    path.write_bytes(bytes(data))
    done = pipemap(command, str(image_set), str(image_set))
    assert_one_line(done, 2, "camera_image3.png: a corrupt PNG image (CRC mismatch")
    assert "libpng" not in done.stderr


# -- outputs -----------------------------------------------------------------------------


def _can_write(folder: Path) -> bool:
    try:
        with tempfile.TemporaryFile(dir=folder):
            return True
    except OSError:
        return False


@pytest.fixture
def unwritable(tmp_path: Path) -> Iterator[Path]:
    """A folder no file can be made in: read-only by mode, or (for root, whom modes do
    not stop) /sys, which refuses new files."""
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        if not _can_write(folder):
            yield folder
        elif Path("/sys").is_dir() and not _can_write(Path("/sys")):
            yield Path("/sys")
        else:
            pytest.skip("no folder here refuses new files (root, without /sys)")
    finally:
        folder.chmod(stat.S_IRWXU)


OUTPUTS = {
    "replay -o": lambda log, d: ["replay", log, "-o", str(d / "map.json")],
    "replay --graphml": lambda log, d: ["replay", log, "--graphml", str(d / "map.graphml")],
    "score --save-results": lambda log, d: ["score", log, "--save-results", str(d / "score")],
    "view --save": lambda log, d: ["view", log, "--save", str(d / "view.rrd")],
    "record -o": lambda log, d: ["record", "--network", "paper", "-o", str(d / "run.mcap")],
    "sim --save-sweeps": lambda log, d: [
        "sim",
        "--network",
        "paper",
        "--save-sweeps",
        str(d / "s"),
    ],
    "experiment --out": lambda log, d: ["experiment", "paper", "--out", str(d / "exp")],
    "batch --out": lambda log, d: [
        "batch",
        str(Path(__file__).resolve().parents[1] / "experiments" / "small.toml"),
        "--out",
        str(d / "batch"),
    ],
}


@pytest.mark.parametrize("name", sorted(OUTPUTS))
def test_an_output_that_cannot_be_written_is_refused_before_any_work(
    unwritable: Path, name: str
) -> None:
    # CPU time, not wall time: on a busy machine starting Python alone takes seconds of
    # wall time. Starting pipemap costs under a second of CPU; building a world, a
    # run or a batch costs tens.
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = pipemap(*OUTPUTS[name](str(STORED), unwritable), timeout=120)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    assert_one_line(done, 2, f"cannot write in folder {unwritable}")
    cpu_s = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    assert cpu_s < 4.0, f"the check came after the work ({cpu_s:.1f} s of CPU)"


@pytest.mark.parametrize(
    "args,output",
    [
        (["score", str(STORED), "--save-results"], "score"),
        (["sim", "--network", "tree:2", "--resolution", "16", "--save-sweeps"], "sweeps"),
    ],
)
def test_folder_outputs_are_replaced_only_with_force(
    tmp_path: Path, args: list[str], output: str
) -> None:
    folder = tmp_path / output
    (folder / "0099").mkdir(parents=True)  # an earlier run's sweep, or anything else
    (folder / "keep.txt").write_text("mine")
    assert_one_line(pipemap(*args, str(folder)), 2, "refusing to replace them without --force")
    done = pipemap(*args, str(folder), "--force")
    assert done.returncode == 0, done.stderr
    assert (folder / "keep.txt").read_text() == "mine"  # --force replaces only its own files
    if output == "sweeps":
        assert not (folder / "0099").exists() and (folder / "0001").is_dir()
    else:
        assert json.loads((folder / "score.json").read_text())["visits"] == 13


# -- the table itself --------------------------------------------------------------------

_TEST_NAME = re.compile(r"`(tests/[\w/]+\.py)::(\w+)`")


def test_every_row_of_the_fault_table_names_a_test_that_exists() -> None:
    table = [
        line
        for line in (REPO / "docs" / "faults.md").read_text().splitlines()
        if line.startswith("|") and not line.startswith("|---")
    ][1:]
    assert len(table) >= 20
    for row in table:
        named = _TEST_NAME.findall(row)
        assert named, f"a row without a test: {row}"
        for path, name in named:
            tree = ast.parse((REPO / path).read_text())
            functions = {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)}
            assert name in functions, f"{path}::{name} (named in docs/faults.md) does not exist"
