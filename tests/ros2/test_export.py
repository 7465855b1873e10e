"""``pipemap export``: a log as a ROS 2 bag that imports back to the same map, and its
trajectories in the TUM format, read by evo's own ``evo_ape``."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pipemap import api  # noqa: I001
from pipemap.cli import main
from tests.ros2.bags import rosbags  # noqa: F401  (skips without the ros extra)

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


def _run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    status = main(args)
    captured = capsys.readouterr()
    return status, captured.out, captured.err


@pytest.fixture(scope="module")
def autonomous(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The autonomous recording exported as a bag, and that bag imported: (bag, log)."""
    folder = tmp_path_factory.mktemp("autonomous")
    api.export_ros2(RECORDINGS / "paper_autonomous.mcap", folder / "bag")
    result = api.import_bag(folder / "bag", folder / "run.mcap")
    assert result.notes == []
    return folder / "bag", folder / "run.mcap"


def _bag_counts(bag: Path) -> dict[str, int]:
    from rosbags.highlevel import AnyReader

    with AnyReader([bag]) as reader:
        counts: dict[str, int] = {}
        for connection in reader.connections:
            counts[connection.topic] = counts.get(connection.topic, 0) + connection.msgcount
        # Read every message too: the metadata's counts could say anything.
        read = {topic: 0 for topic in counts}
        for connection, _, raw in reader.messages():
            reader.deserialize(raw, connection.msgtype)
            read[connection.topic] += 1
    assert read == counts
    return counts


def test_an_export_with_probe_sweeps_imports_back_to_the_same_map_bytes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Active vision: the probe sweeps of each visit go out as markers and come back."""
    log = RECORDINGS / "paper_active.mcap"
    status, out, err = _run(["export", str(log), "--ros2", str(tmp_path / "bag")], capsys)
    assert status == 0, err
    assert (tmp_path / "bag" / "metadata.yaml").is_file()
    status, _, err = _run(
        ["import", str(tmp_path / "bag"), "-o", str(tmp_path / "run.mcap")], capsys
    )
    assert status == 0, err
    original = api.dumps_document(api.replay(log).document())
    assert api.dumps_document(api.replay(tmp_path / "run.mcap").document()) == original
    sweeps = api.open_log(tmp_path / "run.mcap").sweeps()
    assert len(sweeps) == len(api.open_log(log).sweeps())
    assert any(s.probe is not None for s in sweeps)


def test_an_autonomous_run_goes_out_and_back_with_its_ports_and_counts(
    autonomous: tuple[Path, Path],
) -> None:
    """Every sensor stream, /tf with the truth, the exit scans: rosbags' reader counts
    on each topic what ``pipemap info`` counts on the log's, and the bag imports back
    to a log that replays to the same map bytes, ports included."""
    from pipemap.replay.info import log_info as info_document

    log = RECORDINGS / "paper_autonomous.mcap"
    bag = _bag_counts(autonomous[0])
    info = {c["topic"]: c["count"] for c in info_document(log)["channels"]}
    images = info["/robot/camera/image"]
    assert bag == {
        "/pipemap/run": 1,
        "/camera/image/compressed": images,
        "/joint_states": images + info["/robot/wheels"],
        "/pipemap/sweep": info["/robot/camera/sweep"] - images,
        "/imu": info["/robot/imu"],
        "/range/front": info["/robot/tof"],
        "/range/left": info["/robot/tof"],
        "/range/right": info["/robot/tof"],
        "/odom": info["/robot/controller"],
        "/tf": info["/robot/controller"] + info["/truth/pose"],
        "/pipemap/node": info["/robot/node"],
        "/rosout": info["/robot/events"],
    }
    document = api.replay(autonomous[1]).document()
    assert any(node["ports"] for node in document["nodes"])
    assert api.dumps_document(document) == api.dumps_document(api.replay(log).document())


def test_the_bag_holds_the_frames_of_rep_105(tmp_path: Path) -> None:
    from rosbags.highlevel import AnyReader

    api.export_ros2(RECORDINGS / "paper_active.mcap", tmp_path / "bag")
    with AnyReader([tmp_path / "bag"]) as reader:
        tf = [c for c in reader.connections if c.topic == "/tf"]
        frames = set()
        for connection, _, raw in reader.messages(connections=tf):
            for t in reader.deserialize(raw, connection.msgtype).transforms:
                frames.add((t.header.frame_id, t.child_frame_id))
    # The placed robot's controller states (its dead reckoning) and the true pose.
    assert frames == {("odom", "base_link"), ("map", "base_link_truth")}


def test_export_checks_its_outputs_and_the_log_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = str(RECORDINGS / "paper_active.mcap")
    status, _, err = _run(["export", log], capsys)
    assert status == 2 and "--ros2 OUT, --tum DIR or --geojson OUT" in err
    status, _, err = _run(
        ["export", str(tmp_path / "none.mcap"), "--ros2", str(tmp_path / "b")], capsys
    )
    assert status == 2 and len(err.splitlines()) == 1 and not (tmp_path / "b").exists()
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "keep.txt").write_text("earlier")
    status, _, err = _run(["export", log, "--ros2", str(tmp_path / "b")], capsys)
    assert status == 2 and "refusing to replace" in err
    assert (tmp_path / "b" / "keep.txt").read_text() == "earlier"
    status, _, err = _run(["export", log, "--ros2", str(tmp_path / "b"), "--force"], capsys)
    assert status == 0, err
    assert (tmp_path / "b" / "metadata.yaml").is_file()


def test_tum_trajectories_are_read_by_evo_ape(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The dead reckoning against the truth, by evo's own command line (aligned: the
    dead reckoning is in the start's frame)."""
    evo_ape = shutil.which("evo_ape") or str(Path(sys.executable).parent / "evo_ape")
    if not Path(evo_ape).exists():
        pytest.skip("evo is not installed (pip install evo)")
    log = RECORDINGS / "paper_autonomous.mcap"
    status, out, err = _run(["export", str(log), "--tum", str(tmp_path / "tum")], capsys)
    assert status == 0, err
    assert "10119 dead-reckoned poses, 10120 true poses, 13 junctions" in out
    env = {**os.environ, "HOME": str(tmp_path), "MPLBACKEND": "Agg"}
    done = subprocess.run(
        [evo_ape, "tum", "truth.tum", "estimated.tum", "--align", "--save_results", "ape.zip"],
        cwd=tmp_path / "tum",
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    import zipfile

    with zipfile.ZipFile(tmp_path / "tum" / "ape.zip") as results:
        stats = json.loads(results.read("stats.json"))
    # The dead reckoning drifts by millimetres over the paper's network (about 15 m).
    assert 0.0 < stats["rmse"] < 0.05
    rows = (tmp_path / "tum" / "junctions.csv").read_text().splitlines()
    assert rows[0] == "visit,x_m,y_m,odometer_m,true_node,true_x_m,true_y_m"
    assert len(rows) == 14 and rows[1].startswith("1,") and ",S," in rows[1]


def test_a_log_without_truth_has_no_true_trajectory(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    api.export_ros2(RECORDINGS / "paper_autonomous.mcap", tmp_path / "bag")
    api.import_bag(tmp_path / "bag", tmp_path / "run.mcap")
    status, out, err = _run(
        ["export", str(tmp_path / "run.mcap"), "--tum", str(tmp_path / "tum")], capsys
    )
    assert status == 0
    assert "no ground truth" in err and not (tmp_path / "tum" / "truth.tum").exists()
    assert "10119 dead-reckoned poses, 0 true poses" in out
