"""``pipemap view --save``: the recording, read back with rerun's own tools.

The module records one small run once (``pipemap record --network tree:3 --resolution
64 --view --save``: 5 sweeps, its log and its view), saves its view again with
``pipemap view`` and checks them with
``rerun rrd verify`` / ``rerun rrd compare`` and rerun's chunk reader
(``rerun.chunk.RrdReader``): every image and pose is there, the high-rate sensor
streams at 10 a second (every sample with ``--max-rate 0``), on the ``sim_time``
timeline alone, and the map grows into the replay's map.
"""

from __future__ import annotations

import dataclasses
import math
import socket
import subprocess
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest

from pipemap import viewing
from pipemap.cli import main
from pipemap.recorder import Topic, read_log
from pipemap.recorder.schemas import CompressedImage, Ranges
from pipemap.replay import FileSource, StreamSource, replay
from pipemap.replay import view as view_module
from pipemap.replay.view import save_view
from tests.logs import rerun_cli, sweeps_started

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


def view(*args: str) -> subprocess.CompletedProcess[str]:
    """``pipemap view`` as a user runs it, in a fresh interpreter."""
    return subprocess.run(
        [sys.executable, "-m", "pipemap", "view", *args],
        capture_output=True,
        text=True,
        timeout=300,
    )


#: The module's run: tree:3 at seed 0 sweeps 5 times (its 3 nodes, 2 of them again on
#: the way back), 6 images each: the view of a whole run, at a fraction of the cost of
#: the paper network's (whose log is about three times as long).
TREE_RUN = ["--network", "tree:3", "--resolution", "64"]


@pytest.fixture(scope="module")
def recorded_and_viewed(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Path, subprocess.CompletedProcess[str]]:
    """``pipemap record ... --view --save`` of :data:`TREE_RUN`, once for the module:
    its log (beside it, the view it saved) and the command's outcome."""
    log = tmp_path_factory.mktemp("recorded") / "run.mcap"
    done = subprocess.run(
        [sys.executable, "-m", "pipemap", "record", *TREE_RUN, "-o", str(log), "--view", "--save"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    return log, done


@pytest.fixture(scope="module")
def run_log(recorded_and_viewed: tuple[Path, subprocess.CompletedProcess[str]]) -> Path:
    """The module's recorded log (tests only read it)."""
    log, done = recorded_and_viewed
    assert done.returncode == 0, done.stderr
    return log


@pytest.fixture(scope="module")
def saved(run_log: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("view") / "run.rrd"
    done = view(str(run_log), "--save", str(path))
    assert done.returncode == 0, done.stderr
    sweeps, visits = sweeps_started(run_log), len(replay(FileSource(run_log)).visits)
    assert sweeps == visits > 0  # a run without probe sweeps: one sweep a visit
    expected = f"viewed {run_log}: {sweeps} sweeps, {6 * sweeps} images, {visits} visits"
    assert done.stdout.startswith(expected)
    return path


def read_chunks(path: Path) -> dict[str, list[Any]]:
    """The recording's chunks by entity path (the first recording store of the file)."""
    from rerun.chunk import RrdReader

    by_entity: dict[str, list[Any]] = defaultdict(list)
    for chunk in RrdReader(path).stream().to_chunks():
        by_entity[chunk.entity_path].append(chunk)
    return by_entity


@pytest.fixture(scope="module")
def chunks(saved: Path) -> dict[str, list[Any]]:
    return read_chunks(saved)


@pytest.fixture(scope="module")
def full(run_log: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The run viewed with every message of every stream (``--max-rate 0``)."""
    path = tmp_path_factory.mktemp("view") / "full.rrd"
    done = view(str(run_log), "--save", str(path), "--max-rate", "0")
    assert done.returncode == 0, done.stderr
    return path


def rows(chunks: dict[str, list[Any]], entity: str, component: str) -> int:
    """Rows of ``entity`` on the timeline that hold ``component``."""
    return sum(
        c.num_rows
        for c in chunks[entity]
        if not c.is_static and component in c.to_record_batch().schema.names
    )


def column(chunks: dict[str, list[Any]], entity: str, name: str) -> list[Any]:
    """Every timeline value of column ``name`` of ``entity``, in time order."""
    values: list[tuple[int, Any]] = []
    for c in chunks[entity]:
        batch = c.to_record_batch()
        if not c.is_static and name in batch.schema.names:
            times = batch.column("sim_time").cast("int64").to_pylist()
            values.extend(zip(times, batch.column(name).to_pylist(), strict=True))
    return [v for _, v in sorted(values, key=lambda tv: tv[0])]


def test_rerun_verifies_the_recording(saved: Path) -> None:
    done = rerun_cli("rrd", "verify", str(saved))
    assert done.returncode == 0, done.stderr


def test_every_image_pose_and_sample_is_there(run_log: Path, full: Path) -> None:
    chunks = read_chunks(full)
    counts = read_log(run_log).counts
    images = 6 * sweeps_started(run_log)
    assert rows(chunks, "/camera/image", "EncodedImage:blob") == counts[Topic.IMAGE] == images
    assert rows(chunks, "/world/robot", "Transform3D:translation") == counts[Topic.TRUE_POSE]
    series = {
        "/sensors/tof/range_m": (Topic.RANGES, 3),
        "/sensors/imu/yaw_rate_rps": (Topic.IMU, 1),
        "/sensors/imu/accel_mps2": (Topic.IMU, 2),
        "/sensors/wheels/ticks": (Topic.WHEELS, 2),
        "/controller/linear_mps": (Topic.CONTROLLER, 1),
        "/controller/angular_rps": (Topic.CONTROLLER, 1),
    }
    for entity, (topic, width) in series.items():
        values = column(chunks, entity, "Scalars:scalars")
        assert len(values) == counts[topic], entity
        assert {len(v) for v in values} == {width}, entity
    assert rows(chunks, "/world/robot/tof", "Arrows3D:vectors") == counts[Topic.RANGES]
    # One camera direction per sweep START and IMAGE, an empty one at each END.
    assert rows(chunks, "/world/robot/camera", "Arrows3D:vectors") == counts[Topic.SWEEP]
    assert 0 < rows(chunks, "/log/controller", "TextLog:text") < counts[Topic.CONTROLLER] / 10
    trail = [e for e in chunks if e.startswith("/world/trajectory/")]
    assert sum(rows(chunks, e, "LineStrips3D:strips") for e in trail) > 100
    static = [c for c in chunks["/world/network/nodes"] if c.is_static]
    labels = static[0].to_record_batch().column("Points3D:labels").to_pylist()[0]
    assert sorted(labels) == ["S", "n1", "n2"]


def test_range_rays_are_as_long_as_the_ranges(run_log: Path, chunks: dict[str, list[Any]]) -> None:
    logged = [m for m in read_log(run_log).messages if m.topic == Topic.RANGES]
    first = Ranges.FromString(logged[0].data)
    rays = column(chunks, "/world/robot/tof", "Arrows3D:vectors")[0]
    lengths = [math.hypot(*ray) for ray in rays]
    expected = [first.front_m, first.front_left_m, first.front_right_m]
    assert lengths == pytest.approx(expected, abs=1e-6)
    # front, then 40 degrees to the left, then 40 degrees to the right
    angles = [math.degrees(math.atan2(ray[1], ray[0])) for ray in rays]
    assert angles == pytest.approx([0.0, 40.0, -40.0], abs=1e-3)


def test_images_are_the_logged_pngs_at_their_log_times(
    run_log: Path, chunks: dict[str, list[Any]]
) -> None:
    logged = [m for m in read_log(run_log).messages if m.topic == Topic.IMAGE]
    first = CompressedImage.FromString(logged[0].data).data
    blobs = column(chunks, "/camera/image", "EncodedImage:blob")
    assert bytes(blobs[0][0]) == first
    times = sorted(
        t
        for c in chunks["/camera/image"]
        for t in c.to_record_batch().column("sim_time").cast("int64").to_pylist()
    )
    assert times == [m.log_time_ns for m in logged]


def test_the_map_grows_into_the_replay_map(tmp_path: Path) -> None:
    # A stored 96 px log: at 32 px the localizer makes all visits one junction.
    source = FileSource(RECORDINGS / "paper_autonomous.mcap")
    result = replay(source)
    save_view(source, result, tmp_path / "paper.rrd")
    chunks = read_chunks(tmp_path / "paper.rrd")
    nodes = column(chunks, "/map", "GraphNodes:node_ids")
    edges = column(chunks, "/map", "GraphEdges:edges")
    decisions = column(chunks, "/log/decisions", "TextLog:text")
    assert len(nodes) == len(edges) == len(decisions) == len(result.visits) == 13
    assert nodes[0] == ["0"] and edges[0] == []
    assert nodes[-1] == [str(n) for n in range(result.topomap.node_count)]
    assert len(nodes[-1]) == 7 and len(edges[-1]) == len(result.topomap.edges()) == 6
    final = {tuple(sorted(e.values())) for e in edges[-1]}
    assert final == {tuple(sorted((str(e.u), str(e.v)))) for e in result.topomap.edges()}
    for visit, text in zip(result.visits, decisions, strict=True):
        d = visit.decision
        assert text[0].startswith(f"visit {visit.visit_id:04d} -> node {d.node}; ")
        assert ("; known; " if d.known else "; new; ") in text[0]
        similarity = "-" if d.candidate is None else f"{d.similarity:.3f}"
        assert f"similarity {similarity};" in text[0]


def test_sim_time_is_the_only_timeline(chunks: dict[str, list[Any]]) -> None:
    timed = [c for entity in chunks.values() for c in entity if not c.is_static]
    assert timed and all(c.timeline_names == ["sim_time"] for c in timed)


def test_two_saves_of_one_log_compare_equal(run_log: Path, saved: Path, tmp_path: Path) -> None:
    # The same rows: rerun's batcher groups rows into chunks by its own clock, so on a
    # loaded machine two saves of one log hold the rows in other chunks, which
    # `rerun rrd compare` (chunk by chunk, even --unordered) reports as a difference.
    again = tmp_path / "again.rrd"
    done = view(str(run_log), "--save", str(again))
    assert done.returncode == 0, done.stderr
    assert recorded_rows(saved) == recorded_rows(again)


def test_the_command_replaying_in_a_child_process_saves_what_one_process_saves(
    run_log: Path, saved: Path, tmp_path: Path
) -> None:
    # `pipemap view` replays in a forked child while it reads and logs the streams
    # itself, as they come from the file.
    alone = tmp_path / "alone.rrd"
    save_view(StreamSource(run_log), replay(FileSource(run_log)), alone)
    assert recorded_rows(saved) == recorded_rows(alone)


def test_the_command_without_a_child_process_saves_the_same(
    run_log: Path,
    saved: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capfd: pytest.CaptureFixture[str],
) -> None:
    # Where the system cannot fork, one process does it all.
    monkeypatch.setattr(viewing, "_can_fork", lambda: False)
    alone = tmp_path / "alone.rrd"
    status, out, err = run(["view", str(run_log), "--save", str(alone)], capfd)
    assert status == 0, err
    assert f"written to {alone}" in out
    assert recorded_rows(saved) == recorded_rows(alone)


def no_display(monkeypatch: pytest.MonkeyPatch) -> None:
    """As on a headless machine: no X11 or Wayland display."""
    for variable in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(variable, raising=False)


def free_port() -> int:
    """A loopback port nothing listens on (as the system found it a moment ago)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def run(argv: list[str], capfd: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        status = main(argv)
    except SystemExit as exc:
        status = exc.code if isinstance(exc.code, int) else 1
    out, err = capfd.readouterr()
    return status, out, err


@pytest.mark.parametrize(
    ("case", "expected"),
    [
        ("missing", "no such file"),
        ("not_mcap", "not an MCAP file"),
        ("wrong_flag", "unrecognized arguments: --frobnicate"),
        ("exists", "exists; refusing to overwrite without --force"),
        ("suffix", "a rerun recording is saved as a .rrd file"),
        ("no_folder", "does not exist"),
        ("no_display", "no display for the rerun viewer"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    case: str,
    expected: str,
    run_log: Path,
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    no_display(monkeypatch)
    not_mcap = tmp_path / "notes.mcap"
    not_mcap.write_text("not a log\n")
    existing = tmp_path / "old.rrd"
    existing.write_bytes(b"keep me")
    log, out = str(run_log), str(tmp_path / "new.rrd")
    argv = {
        "missing": [str(tmp_path / "nothing.mcap"), "--save", out],
        "not_mcap": [str(not_mcap), "--save", out],
        "wrong_flag": [log, "--frobnicate"],
        "exists": [log, "--save", str(existing)],
        "suffix": [log, "--save", str(tmp_path / "new.mcap")],
        "no_folder": [log, "--save", str(tmp_path / "absent" / "new.rrd")],
        "no_display": [log],
    }[case]
    status, stdout, stderr = run(["view", *argv], capfd)
    assert status == 2
    assert stdout == ""
    assert len(stderr.splitlines()) == 1 and stderr.startswith("pipemap: error: ")
    assert expected in stderr
    assert existing.read_bytes() == b"keep me"
    assert not (tmp_path / "new.rrd").exists()


def test_record_view_save_writes_the_view_beside_the_log(
    recorded_and_viewed: tuple[Path, subprocess.CompletedProcess[str]],
) -> None:
    log, done = recorded_and_viewed
    assert done.returncode == 0, done.stderr
    rrd = log.with_suffix(".rrd")
    last = done.stdout.splitlines()[-1]
    # tree:3's run at seed 0 sweeps 5 times, 6 images each (see TREE_RUN).
    assert last.startswith(f"viewed {log}: 5 sweeps, 30 images, 5 visits, ")
    assert last.endswith(f" junctions, written to {rrd}")
    assert rerun_cli("rrd", "verify", str(rrd)).returncode == 0
    images = read_chunks(rrd)
    assert rows(images, "/camera/image", "EncodedImage:blob") == read_log(log).counts[Topic.IMAGE]


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        (["--save"], "--save: writes the view of the run, so it needs --view"),
        (["--view"], "no display for the rerun viewer"),
        (["--view", "--save"], "exists; refusing to overwrite without --force"),
        (["--connect", "{url}"], "--connect: streams the run to a viewer, so it needs --view"),
        (["--view", "--connect", "http://127.0.0.1:1/x"], "not a rerun gRPC proxy URL"),
        (["--view", "--connect", "rerun+http://127.0.0.1:99999/proxy"], "the port is not"),
        (["--view", "--connect", "{closed}"], "no rerun viewer or server answers at"),
        (["--view", "--save", "--connect", "{url}"], "choose one"),
    ],
)
def test_record_view_is_checked_before_the_run(
    extra: list[str],
    expected: str,
    tmp_path: Path,
    capfd: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    no_display(monkeypatch)
    (tmp_path / "run.rrd").write_bytes(b"keep me")
    closed = f"rerun+http://127.0.0.1:{free_port()}/proxy"  # nothing listens there
    extra = [a.format(url="rerun+http://127.0.0.1:9876/proxy", closed=closed) for a in extra]
    log = tmp_path / "run.mcap"
    status, stdout, stderr = run(["record", "--network", "paper", "-o", str(log), *extra], capfd)
    assert status == 2 and stdout == ""
    assert len(stderr.splitlines()) == 1 and expected in stderr
    assert not log.exists()  # refused before the run: no log written
    assert (tmp_path / "run.rrd").read_bytes() == b"keep me"


def recorded_rows(path: Path) -> dict[str, list[str]]:
    """Every row of the recording by entity, as text, in order: the data without how
    rerun cut it into chunks (which differs with how it was sent) or its row ids.
    Static rows are what an entity's last static write left."""
    import json

    timed: dict[str, list[str]] = defaultdict(list)
    static: dict[str, str] = {}
    for entity, chunks in read_chunks(path).items():
        for chunk in chunks:
            batch = chunk.to_record_batch()
            names = [n for n in batch.schema.names if n != "rerun.controls.RowId"]
            values = {
                n: batch.column(n).cast("int64").to_pylist()
                if n == "sim_time"
                else batch.column(n).to_pylist()
                for n in names
            }
            for row in range(batch.num_rows):
                text = json.dumps({n: values[n][row] for n in names}, sort_keys=True)
                if chunk.is_static:
                    static[f"{entity} {sorted(names)}"] = text
                else:
                    timed[entity].append(text)
    rows = {e: sorted(texts) for e, texts in timed.items()}
    rows.update({f"static {key}": [text] for key, text in static.items()})
    return rows


@pytest.mark.parametrize("window", [997, 10**9])
def test_a_log_viewed_a_window_at_a_time_is_the_whole_log_viewed(
    run_log: Path, full: Path, tmp_path: Path, window: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``pipemap view`` reads and logs a log a window of messages at a time (the
    module's log: about 34 000 messages, one window of 50 000 by default; the paper
    network's run, about 80 000, two): in windows of 997
    (each carrying the trajectory, the styles logged and the controller's state to
    the next) or in one, the same rows. (``rerun rrd compare`` compares chunks,
    and the windows cut the images and series into other chunks.)"""
    monkeypatch.setattr(view_module, "VIEW_WINDOW", window)
    windows: list[int] = []
    real = view_module.log_robot

    def counting(rec: Any, messages: dict[str, list[Any]], *args: Any) -> None:
        windows.append(sum(map(len, messages.values())))
        real(rec, messages, *args)

    monkeypatch.setattr(view_module, "log_robot", counting)
    again = tmp_path / f"window-{window}.rrd"
    save_view(StreamSource(run_log), replay(FileSource(run_log)), again, 0.0)
    assert recorded_rows(again) == recorded_rows(full)
    viewed = sum(read_log(run_log).counts.values())
    assert len(windows) == -(-viewed // window)  # a window of messages at a time
    # A style is logged once, not once a window.
    body = [c for c in read_chunks(again)["/world/robot/body"] if c.is_static]
    assert sum(c.num_rows for c in body) == 1


def test_every_source_gives_the_log_in_file_order(run_log: Path) -> None:
    """A view reads any source in the same windows: a file read whole and a file read
    as it goes hand out the same messages in the same (file) order."""
    whole = list(FileSource(run_log).every_message())
    assert len(whole) > 1000
    assert list(StreamSource(run_log).every_message()) == whole
    assert [m.topic for m in whole] != sorted(m.topic for m in whole)  # not by topic


def test_the_command_never_reads_the_log_whole(
    run_log: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capfd: pytest.CaptureFixture[str],
) -> None:
    """``pipemap view`` reads the file as it goes, for the replay and for the view
    (here in one process): the reader that holds a whole log is never called."""
    from pipemap.replay import source as source_module

    def whole(*args: Any, **kwargs: Any) -> None:
        raise AssertionError("the log was read whole")

    monkeypatch.setattr(source_module, "read_log", whole)
    monkeypatch.setattr(viewing, "_can_fork", lambda: False)
    out = tmp_path / "streamed.rrd"
    status, _, err = run(["view", str(run_log), "--save", str(out)], capfd)
    assert status == 0, err
    assert out.exists()


@pytest.mark.parametrize(
    ("probe_moves", "makes_probes"), [("false", False), ("true", True)], ids=["off", "on"]
)
def test_a_decision_is_a_warning_only_where_probes_the_robot_makes_are_missing(
    tmp_path: Path, probe_moves: str, makes_probes: bool
) -> None:
    """At a threshold of 0.6 the stored autonomous run asks for probes its log does not
    hold. Said to be recorded with its probe moves off, those decisions are plain ones
    in the view (as online, the robot made none). Said to make its moves, the probes
    it would have made are missing: those decisions are warnings, unless the robot
    refused each missing probe's move (its log says so)."""
    from pipemap.localizer import LocalizerConfig
    from pipemap.recorder import METADATA_RUN
    from pipemap.replay.source import MemorySource

    contents = read_log(RECORDINGS / "paper_autonomous.mcap")
    run = {**contents.metadata[METADATA_RUN], "probe_moves": probe_moves}
    source = MemorySource(list(contents.messages), run, "paper_autonomous.mcap")
    result = replay(source, LocalizerConfig(threshold=0.6))
    # A probe whose move the robot refused (its log says so) is not missing.
    unanswered = [sum(p.similarity is None for p in v.decision.probes) for v in result.visits]
    short = [n > v.probes_refused for n, v in zip(unanswered, result.visits, strict=True)]
    assert any(short)
    # The log holds refused moves: some visits lack only probes the robot refused.
    assert any(n > 0 and not s for n, s in zip(unanswered, short, strict=True))
    save_view(source, result, tmp_path / "view.rrd")
    levels = column(read_chunks(tmp_path / "view.rrd"), "/log/decisions", "TextLog:level")
    expected = ["WARN" if s and makes_probes else "INFO" for s in short]
    assert [level[0] for level in levels] == expected


@pytest.mark.parametrize(
    ("probe_moves", "makes_probes"), [("false", False), ("true", True)], ids=["off", "on"]
)
def test_the_live_view_warns_where_the_saved_view_does(
    tmp_path: Path, probe_moves: str, makes_probes: bool
) -> None:
    """Shown live, the same run's decisions are warnings exactly where a saved view's
    are: a probe whose move the robot refused is not missing, nor is one a robot that
    makes no probe moves never made (the test above shows the log holds both kinds)."""
    from pipemap.localizer import LocalizerConfig
    from pipemap.recorder import METADATA_RUN
    from pipemap.replay.live import LiveView
    from pipemap.replay.source import MemorySource

    contents = read_log(RECORDINGS / "paper_autonomous.mcap")
    run = {**contents.metadata[METADATA_RUN], "probe_moves": probe_moves}
    config = LocalizerConfig(threshold=0.6)
    rec = view_module.recording(run)
    rec.save(tmp_path / "live.rrd")
    with LiveView(rec, run, config) as live:
        live.show(list(contents.messages))
    levels = column(read_chunks(tmp_path / "live.rrd"), "/log/decisions", "TextLog:level")
    result = replay(MemorySource(list(contents.messages), run, "paper_autonomous.mcap"), config)
    expected = ["WARN" if v.probes_not_in_log else "INFO" for v in result.visits]
    assert [level[0] for level in levels] == expected
    assert ("WARN" in expected) == makes_probes
    # Some visit lacks probes only because the robot refused their moves: no warning.
    refused_only = [
        v.probes_refused > 0 and v.probes_not_in_log == 0 and makes_probes for v in result.visits
    ]
    assert any(refused_only) == makes_probes


def test_a_decision_says_when_its_fit_matched_only_the_first_stages() -> None:
    """A two-view fit on the first quarter of a junction's keypoints counts that
    quarter's inliers: the line says so, lest a reader take them for a weak fit."""
    log = FileSource(RECORDINGS / "paper_autonomous.mcap")
    visit = next(v for v in replay(log).visits if v.decision.two_view is not None)
    fit = visit.decision.two_view
    assert fit is not None and fit.stages is None
    whole = view_module.describe_decision(visit)
    assert f"({fit.inliers} inliers)" in whole
    decision = dataclasses.replace(visit.decision, two_view=dataclasses.replace(fit, stages=1))
    quarter = dataclasses.replace(visit, decision=decision)
    line = view_module.describe_decision(quarter)
    assert f"({fit.inliers} inliers of the first 1 stage(s))" in line
    assert line.replace(" of the first 1 stage(s)", "") == whole


def first_of_each_slot(run_log: Path, topic: str, period_ns: int) -> list[int]:
    """Log times of the first message of ``topic`` in each slot of ``period_ns``."""
    times = sorted(m.log_time_ns for m in read_log(run_log).messages if m.topic == topic)
    firsts: dict[int, int] = {}
    for t in times:
        firsts.setdefault(t // period_ns, t)
    return sorted(firsts.values())


def test_the_view_shows_the_high_rate_streams_at_10_hz_by_default(
    run_log: Path, chunks: dict[str, list[Any]]
) -> None:
    """Ranges (20 Hz), IMU (100 Hz) and wheels (50 Hz): the first message of each
    tenth of a second of log time, and nothing else; the other streams are whole."""
    got = chunks
    counts = read_log(run_log).counts
    streams = {
        "/sensors/tof/range_m": Topic.RANGES,
        "/world/robot/tof": Topic.RANGES,
        "/sensors/imu/yaw_rate_rps": Topic.IMU,
        "/sensors/imu/accel_mps2": Topic.IMU,
        "/sensors/wheels/ticks": Topic.WHEELS,
    }
    for entity, topic in streams.items():
        expected = first_of_each_slot(run_log, topic, 100_000_000)
        shown = sorted(
            t
            for c in got[entity]
            if not c.is_static
            for t in c.to_record_batch().column("sim_time").cast("int64").to_pylist()
        )
        assert shown == expected, entity
        assert len(shown) < counts[topic] / 1.9, entity  # thinned out, even the 20 Hz one
    assert len(column(got, "/controller/linear_mps", "Scalars:scalars")) == counts[Topic.CONTROLLER]
    assert rows(got, "/world/robot", "Transform3D:translation") == counts[Topic.TRUE_POSE]
    assert rows(got, "/camera/image", "EncodedImage:blob") == counts[Topic.IMAGE]


def test_a_decimated_view_a_window_at_a_time_is_the_whole_log_decimated(
    run_log: Path, saved: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The slot of the last message shown carries over from one window to the next."""
    monkeypatch.setattr(view_module, "VIEW_WINDOW", 997)
    again = tmp_path / "windows.rrd"
    save_view(StreamSource(run_log), replay(FileSource(run_log)), again)
    assert recorded_rows(again) == recorded_rows(saved)


def test_a_negative_rate_is_refused(run_log: Path, tmp_path: Path) -> None:
    done = view(str(run_log), "--save", str(tmp_path / "x.rrd"), "--max-rate", "-1")
    assert done.returncode == 2
    assert done.stderr.startswith("pipemap: error:") and "--max-rate" in done.stderr
    assert not (tmp_path / "x.rrd").exists()
