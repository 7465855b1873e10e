"""``pipemap record`` and ``pipemap info`` end to end, as subprocesses."""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from pipemap.recorder import (
    METADATA_RESULT,
    METADATA_RUN,
    TOPICS,
    Integrity,
    Topic,
    read_log,
    schemas,
)
from tests.logs import SMALL_RUN, record, recorded


def pipemap(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args], capture_output=True, text=True, timeout=300
    )


#: A run of three junctions under even light (the lamp off): recorded once for the
#: module, read by the determinism and the lighting tests. (The shared paper run's
#: determinism is checked against a recording made in one process, in other threads,
#: by tests/recorder/test_inline.py.)
EVEN_TREE = ("--lighting", "even", "--network", "tree:3")


@pytest.fixture(scope="module")
def even_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return recorded(tmp_path_factory, "even", *EVEN_TREE)


def test_the_same_seed_gives_the_same_bytes(even_run: Path, tmp_path: Path) -> None:
    again = tmp_path / "again.mcap"
    done = record(again, *EVEN_TREE)
    assert done.returncode == 0, done.stderr
    assert again.read_bytes() == even_run.read_bytes()


def test_a_run_logs_every_stream(recorded_run: Path) -> None:
    contents = read_log(recorded_run)
    assert contents.integrity is Integrity.OK
    for topic in (Topic.RANGES, Topic.IMU, Topic.WHEELS, Topic.CONTROLLER, Topic.EVENTS):
        assert contents.counts[topic] > 100 or topic == Topic.EVENTS, topic
    # Sensor rates over the run: 20 Hz rangers, 100 Hz IMU, 50 Hz encoders.
    seconds = contents.duration_ns / 1e9
    assert contents.counts[Topic.IMU] == pytest.approx(100 * seconds, rel=0.01)
    assert contents.counts[Topic.WHEELS] == pytest.approx(50 * seconds, rel=0.01)
    assert contents.counts[Topic.RANGES] == pytest.approx(20 * seconds, rel=0.01)
    by_topic: dict[str, list[bytes]] = {}
    for m in contents.messages:
        by_topic.setdefault(m.topic, []).append(m.data)
    commands = [schemas.SweepCommand.FromString(d) for d in by_topic[Topic.SWEEP]]
    starts = [c for c in commands if c.phase == schemas.SweepCommand.START]
    images = [c for c in commands if c.phase == schemas.SweepCommand.IMAGE]
    assert len(starts) == 13 and len(images) == 13 * 6
    assert len(by_topic[Topic.IMAGE]) == 13 * 6
    assert [c.image_index for c in images[:6]] == list(range(6))
    truths = [schemas.TrueSweep.FromString(d).node for d in by_topic[Topic.TRUE_SWEEP]]
    assert truths == list("SABACDCFCECAS")
    decisions = [schemas.Decision.FromString(d) for d in by_topic[Topic.DECISION]]
    assert [d.visit_id for d in decisions] == list(range(1, 14))
    nodes = [schemas.NodeEvent.FromString(d) for d in by_topic[Topic.NODE]]
    arrivals = [n for n in nodes if n.kind == schemas.NodeEvent.ARRIVAL]
    departures = [n for n in nodes if n.kind == schemas.NodeEvent.DEPARTURE]
    assert len(arrivals) == 13 and len(departures) == 12  # it stays at the start
    meta = contents.metadata[METADATA_RUN]
    assert (meta["network"], meta["seed"], meta["condition"]) == ("paper", "3", "autonomous")
    assert contents.metadata[METADATA_RESULT]["status"] == "finished"


def test_each_visit_logs_its_exit_scan_and_the_decision_its_ports(recorded_run: Path) -> None:
    contents = read_log(recorded_run, keep=lambda t: t in (Topic.NODE, Topic.DECISION))
    nodes = [
        schemas.NodeEvent.FromString(m.data) for m in contents.messages if m.topic == Topic.NODE
    ]
    scans = [n for n in nodes if n.kind == schemas.NodeEvent.EXITS]
    # One scan per visit, between its arrival and its departure: S A B A C D C F C E C A S.
    assert [len(n.exits_rad) for n in scans] == [1, 3, 1, 3, 4, 1, 4, 1, 4, 1, 4, 3, 1]
    order = [(n.visit_id, n.kind) for n in nodes]
    for visit in range(1, 13):
        a = order.index((visit, schemas.NodeEvent.ARRIVAL))
        e = order.index((visit, schemas.NodeEvent.EXITS))
        d = order.index((visit, schemas.NodeEvent.DEPARTURE))
        assert a < e < d
    odometer = [n.odometer_m for n in scans]
    assert odometer == sorted(odometer) and 13.0 < odometer[-1] < 15.0
    assert all(-math.pi <= e <= math.pi for n in scans for e in n.exits_rad)
    decisions = [
        schemas.Decision.FromString(m.data) for m in contents.messages if m.topic == Topic.DECISION
    ]
    assert [sorted(d.exit_ports) for d in decisions] == [
        list(range(len(n.exits_rad))) for n in scans
    ]
    assert not decisions[0].HasField("arrival_port")
    assert all(d.arrival_port == 0 for d in decisions[1:] if not d.known)
    assert contents.metadata[METADATA_RUN]["explore"] == "map"
    assert contents.metadata[METADATA_RUN]["format_version"] == "2"


def test_truth_and_online_decisions_live_apart_from_the_robot(recorded_run: Path) -> None:
    contents = read_log(recorded_run)
    truth_types = {"pipemap.TrueSweep", "foxglove.FrameTransform", "foxglove.SceneUpdate"}
    for channel in contents.channels.values():
        prefix = channel.topic.split("/")[1]
        assert prefix in ("robot", "truth", "online"), channel.topic
        if channel.schema_name in truth_types:
            assert prefix == "truth", channel.topic
        if channel.schema_name == "pipemap.Decision":
            assert prefix == "online", channel.topic
    # No robot message type has room for a node label or a true pose.
    for topic, message_class in TOPICS:
        if topic.startswith("/robot/"):
            names = {f.name for f in message_class.DESCRIPTOR.fields}
            assert not names & {"node", "true_node", "x_m", "y_m", "translation"}, topic


def test_info_describes_the_log(recorded_run: Path) -> None:
    done = pipemap("info", str(recorded_run), "--json")
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    assert doc["integrity"] == "ok" and doc["sweeps"] == 13 and doc["visits"] == 13
    meta = doc["metadata"]
    assert meta["network"] == "paper" and meta["seed"] == 3  # numbers as numbers
    assert meta["resolution_px"] == 64 and meta["align_sweeps"] is True
    assert isinstance(meta["threshold"], float) and isinstance(meta["simulator"], dict)
    result = meta["result"]
    assert result["status"] == "finished"
    assert result["sweeps"] == doc["sweeps"] and result["visits"] == doc["visits"]
    assert isinstance(result["distance_m"], float) and isinstance(result["duration_ns"], int)
    topics = {c["topic"]: c for c in doc["channels"]}
    assert topics[Topic.IMAGE]["schema"] == "foxglove.CompressedImage"
    assert topics[Topic.IMAGE]["count"] == 78
    assert doc["messages"] == sum(c["count"] for c in doc["channels"])
    assert doc["duration_s"] > 60
    text = pipemap("info", str(recorded_run))
    assert text.returncode == 0 and "integrity  ok" in text.stdout and "/robot/imu" in text.stdout


def test_info_reports_a_cut_log_and_exits_0(recorded_run: Path, tmp_path: Path) -> None:
    data = recorded_run.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    done = pipemap("info", str(cut), "--json")
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    assert doc["integrity"] == "truncated" and doc["messages"] > 0
    assert 0 < doc["sweeps"] < 13


def test_info_reports_a_damaged_log_and_exits_1(recorded_run: Path, tmp_path: Path) -> None:
    data = bytearray(recorded_run.read_bytes())
    data[len(data) // 3] ^= 0x01
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    done = pipemap("info", str(damaged), "--json")
    assert done.returncode == 1, done.stderr
    assert json.loads(done.stdout)["integrity"] == "corrupt"


@pytest.mark.parametrize(
    "content,message",
    [(b"", "empty file"), (b"GARBAGE" * 100, "not an MCAP file")],
)
def test_info_refuses_garbage_in_one_line(tmp_path: Path, content: bytes, message: str) -> None:
    path = tmp_path / "bad.mcap"
    path.write_bytes(content)
    done = pipemap("info", str(path))
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and message in done.stderr
    assert "Traceback" not in done.stderr


def test_record_refuses_to_overwrite(tmp_path: Path) -> None:
    target = tmp_path / "run.mcap"
    target.write_bytes(b"precious")
    done = pipemap("record", *SMALL_RUN, "-o", str(target))
    assert done.returncode == 2 and "--force" in done.stderr
    assert done.stderr.count("\n") == 1
    assert target.read_bytes() == b"precious"


@pytest.mark.parametrize(
    "args,message",
    [
        (["--network", "nowhere:3"], "nowhere"),
        (["--network", "paper", "--start", "Z"], "--start Z"),
        (["--network", "paper", "--resolution", "7"], "resolution"),
        (["--network", "paper", "--condition", "sideways"], "sideways"),
    ],
)
def test_record_refuses_bad_arguments_before_creating_the_file(
    tmp_path: Path, args: list[str], message: str
) -> None:
    target = tmp_path / "run.mcap"
    done = pipemap("record", *args, "-o", str(target))
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and message in done.stderr
    assert not target.exists()


def _start_long_recording(target: Path) -> subprocess.Popen[str]:
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "pipemap",
            "record",
            "--network",
            "tree:4",
            "--seed",
            "1",
            "--resolution",
            "32",
            "-o",
            str(target),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    # Wait until the first sweeps are on disk (each sweep's end is flushed).
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        # The log reads from the start (a placeholder of no messages, then the run's
        # log cut short): wait for a sweep's images in it.
        if target.exists() and read_log(target).counts.get(Topic.IMAGE, 0) > 0:
            return process
        time.sleep(0.2)
    process.kill()
    raise AssertionError("the recording wrote nothing within 120 s")


def test_ctrl_c_leaves_a_valid_log_and_says_so(tmp_path: Path) -> None:
    target = tmp_path / "interrupted.mcap"
    process = _start_long_recording(target)
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 130
    assert "interrupted" in err and str(target) in err and "Traceback" not in err
    contents = read_log(target)
    assert contents.integrity is Integrity.OK
    assert contents.metadata[METADATA_RESULT]["status"] == "interrupted"
    assert contents.counts[Topic.IMAGE] > 0


def test_a_killed_recording_is_closed_by_its_writer(tmp_path: Path) -> None:
    target = tmp_path / "killed.mcap"
    process = _start_long_recording(target)
    process.kill()  # SIGKILL: no handler runs in the recording process
    # The writer holds the same stderr: it is read to its end once the writer is done.
    _, err = process.communicate(timeout=120)
    assert "Traceback" not in err and err == ""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # the writer process finishes on its own
        contents = read_log(target)
        if contents.integrity is Integrity.OK:
            break
        time.sleep(0.2)
    assert contents.integrity is Integrity.OK, contents.problem
    assert contents.metadata[METADATA_RESULT]["status"].startswith("lost its run")
    assert contents.counts[Topic.IMAGE] > 0


def _writer_of(process: subprocess.Popen[str]) -> int:
    children = Path(f"/proc/{process.pid}/task/{process.pid}/children")
    if not children.exists():
        process.kill()
        pytest.skip("no /proc/PID/task/PID/children here: cannot find the writer process")
    [writer] = [int(pid) for pid in children.read_text().split()]
    return writer


def test_a_killed_writer_is_a_crash_exit_3_and_the_log_stays_readable(tmp_path: Path) -> None:
    target = tmp_path / "crashed.mcap"
    process = _start_long_recording(target)
    os.kill(_writer_of(process), signal.SIGKILL)
    _, err = process.communicate(timeout=120)
    assert process.returncode == 3, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert "the log writer process was killed (SIGKILL)" in err and str(target) in err
    contents = read_log(target)
    assert contents.integrity is Integrity.TRUNCATED
    assert contents.counts[Topic.IMAGE] > 0


def test_a_full_disk_is_a_crash_exit_3_in_one_line() -> None:
    done = pipemap("record", *SMALL_RUN, "--network", "tree:3", "-o", "/dev/full", "--force")
    assert done.returncode == 3, done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
    assert "writing /dev/full failed: No space left on device" in done.stderr


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 400 kB file system, mounted for the test (root only)."""
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a small tmpfs needs root and mount(8)")
    folder = tmp_path / "small"
    folder.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=400k", "tmpfs", str(folder)], capture_output=True
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.decode().strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


def test_a_disk_that_fills_keeps_every_complete_sweep_readable(small_disk: Path) -> None:
    target = small_disk / "run.mcap"
    # tree:3's log (about 1.6 MB at 64 px) fills the 400 kB as surely as paper's, in a
    # world a fraction as costly to build.
    done = pipemap("record", *SMALL_RUN, "--network", "tree:3", "-o", str(target))
    assert done.returncode == 3, done.stderr
    assert done.stderr.count("\n") == 1 and "No space left on device" in done.stderr
    info = pipemap("info", "--json", str(target))
    assert info.returncode == 0, info.stderr
    doc = json.loads(info.stdout)
    assert doc["integrity"] == "truncated" and doc["sweeps"] >= 1
    replayed = pipemap("replay", str(target))
    assert replayed.returncode == 0 and len(json.loads(replayed.stdout)["visits"]) == doc["sweeps"]


@pytest.mark.parametrize(
    "extra, explore", [((), "map"), (("--explore", "right-hand"), "right-hand")]
)
def test_record_hands_the_exploration_policy_to_the_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, extra: tuple[str, ...], explore: str
) -> None:
    import pipemap.recorder as package
    from pipemap.cli import main
    from pipemap.recorder import session
    from pipemap.sim.network import build_network

    seen = []

    def fake_record_run(  # type: ignore[no-untyped-def]
        path, settings, network, version, *rest
    ):
        seen.append(settings)
        path.write_bytes(b"")
        return session.RecordResult("finished", True, 0, 0, 0.0, 0, 0, frozenset(), 7)

    # ``pipemap.recorder`` loads it lazily and keeps it once loaded: patched first, so
    # that what it keeps after the test is the real one (patched after the session,
    # its lazy load would keep the fake for every later test).
    monkeypatch.setattr(package, "record_run", fake_record_run, raising=False)
    monkeypatch.setattr(session, "record_run", fake_record_run)
    status = main(["record", "--network", "paper", *extra, "-o", str(tmp_path / "x.mcap")])
    assert status == 0
    assert [s.explore.value for s in seen] == [explore]
    assert seen[0].metadata(build_network("paper"), "t")["explore"] == explore
    done = pipemap("record", "--network", "paper", "--explore", "left-hand", "-o", "x.mcap")
    assert done.returncode == 2 and "--explore" in done.stderr


def test_the_log_records_the_lamp_and_lighting_even_turns_it_off(
    recorded_run: Path, even_run: Path
) -> None:
    from pipemap.recorder.metadata import lamp_strength

    assert lamp_strength(read_log(recorded_run).metadata[METADATA_RUN]) == 1.0
    # A network of three junctions: the lamp is a setting of the run, not of the network
    # (the small run's paper network was only the larger world to build).
    assert lamp_strength(read_log(even_run).metadata[METADATA_RUN]) == 0.0
