"""``pipemap import``: a ROS 2 bag written by rosbags (not by pipemap) made into a
pipemap log, by the contract of docs/ros2.md, and each bad bag refused in one line."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipemap import api  # noqa: I001
from pipemap.cli import main
from pipemap.errors import InputError
from pipemap.recorder import Topic, read_log
from tests.conftest import PAPER_SETS
from tests.ros2.bags import NS, STORE, BagWriter, sweep_bag, write_bag

needs_sets = pytest.mark.skipif(not PAPER_SETS.is_dir(), reason="no shared/paper_imagesets")


def _partition(nodes: list[int]) -> list[int]:
    """Node ids renumbered by first appearance: the same partition, the same list."""
    seen: dict[int, int] = {}
    return [seen.setdefault(n, len(seen)) for n in nodes]


def _jpeg(seed: int, size: tuple[int, int] = (64, 48)) -> bytes:
    rng = np.random.default_rng(seed)
    image = cv2.GaussianBlur(rng.integers(0, 256, (size[1], size[0], 3), dtype=np.uint8), (5, 5), 0)
    ok, data = cv2.imencode(".jpg", image)
    assert ok
    return data.tobytes()


def _sweeps(
    bag: BagWriter, starts_s: list[float], n: int = 6, size: tuple[int, int] = (64, 48)
) -> None:
    """One sweep of ``n`` images 0.2 s apart at each start, the joint turning clockwise."""
    for s, start in enumerate(starts_s):
        for k in range(n):
            t = int((start + 0.2 * k) * NS)
            bag.joint(t, ["camera_yaw"], [-2 * math.pi * k / n])
            bag.image(t, _jpeg(100 * s + k, size))


def _run(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    status = main(args)
    captured = capsys.readouterr()
    return status, captured.out, captured.err


#: Five of the paper's sets, in the order of the bags' sweeps.
MAPPED_SETS = ("1", "4", "2", "10", "3")


@pytest.fixture(scope="module")
def mapped_partition() -> list[int]:
    """The partition ``pipemap map`` gives :data:`MAPPED_SETS`: made once, the same
    for both storages."""
    folders = [PAPER_SETS / name for name in MAPPED_SETS]
    return _partition([v["node"] for v in api.map_image_sets(folders)["visits"]])


@needs_sets
@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_a_bag_of_the_paper_sets_maps_as_pipemap_map_does(
    tmp_path: Path, storage: str, mapped_partition: list[int]
) -> None:
    """JPEG CompressedImage messages and a camera_yaw joint, written by rosbags: the
    imported log replays to the partition ``pipemap map`` gives the same folders."""
    folders = [PAPER_SETS / name for name in MAPPED_SETS]
    bag = sweep_bag(tmp_path / "bag", folders, storage=storage)
    result = api.import_bag(bag, tmp_path / "run.mcap")
    assert (result.sweeps, result.visits) == (5, 5)
    replayed = [v["node"] for v in api.replay(tmp_path / "run.mcap").document()["visits"]]
    assert _partition(replayed) == mapped_partition == [0, 1, 0, 2, 0]


def test_import_writes_a_log_that_replay_and_view_take_and_score_refuses(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = write_bag(tmp_path / "bag", lambda b: _sweeps(b, [1.0, 10.0, 20.0]))
    status, out, err = _run(["import", str(bag), "-o", str(tmp_path / "run.mcap")], capsys)
    assert status == 0, err
    assert "3 sweeps (18 images) in 3 visits" in out
    assert "no range readings" in err and "the map has no ports" in err
    log = read_log(tmp_path / "run.mcap")
    assert log.counts[Topic.IMAGE] == 18 and log.counts[Topic.SWEEP] == 3 * 8
    status, out, _ = _run(["replay", str(tmp_path / "run.mcap")], capsys)
    assert status == 0 and '"visits"' in out
    status, _, err = _run(["score", str(tmp_path / "run.mcap")], capsys)
    assert status == 2 and "no ground truth" in err
    status, _, err = _run(
        ["view", str(tmp_path / "run.mcap"), "--save", str(tmp_path / "run.rrd")], capsys
    )
    assert status == 0, err
    assert (tmp_path / "run.rrd").stat().st_size > 0


def test_the_same_bag_imports_to_the_same_bytes(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", lambda b: _sweeps(b, [1.0, 10.0]))
    api.import_bag(bag, tmp_path / "a.mcap")
    api.import_bag(bag, tmp_path / "b.mcap")
    assert (tmp_path / "a.mcap").read_bytes() == (tmp_path / "b.mcap").read_bytes()


def test_sweeps_are_split_by_gaps_longer_than_sweep_gap_s(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "bag", lambda b: _sweeps(b, [1.0, 3.5, 10.0]))
    # The first two sweeps are 1.5 s apart: one burst of 12 images at the default 3 s.
    with pytest.raises(InputError, match="clockwise by 360/12"):
        api.import_bag(bag, tmp_path / "a.mcap")
    spec = tmp_path / "spec.toml"
    spec.write_text("sweep_gap_s = 1.0\n")
    assert api.import_bag(bag, tmp_path / "b.mcap", spec).sweeps == 3


def test_a_marker_topic_splits_sweeps_where_gaps_do_not(tmp_path: Path) -> None:
    def fill(b: BagWriter) -> None:
        _sweeps(b, [1.0, 2.5])  # 0.3 s apart: one burst by gaps
        for t in (0.9, 2.4):
            b.write(
                "/sweep",
                "std_msgs/msg/String",
                int(t * NS),
                STORE.types["std_msgs/msg/String"](data="sweep"),
            )

    bag = write_bag(tmp_path / "bag", fill)
    with pytest.raises(InputError, match="clockwise by 360/12"):
        api.import_bag(bag, tmp_path / "a.mcap")
    spec = tmp_path / "spec.toml"
    spec.write_text('sweep_topic = "/sweep"\n')
    assert api.import_bag(bag, tmp_path / "b.mcap", spec).sweeps == 2


def test_the_spec_names_the_camera_topic_and_joint(tmp_path: Path) -> None:
    def fill(b: BagWriter) -> None:
        for k in range(4):
            t = NS + k * NS // 5
            b.joint(t, ["pan"], [math.pi - 2 * math.pi * k / 4])
            b.image(t, _jpeg(k), topic="/cam/compressed")

    bag = write_bag(tmp_path / "bag", fill)
    with pytest.raises(InputError, match="/camera/image/compressed: no such topic"):
        api.import_bag(bag, tmp_path / "a.mcap")
    spec = tmp_path / "spec.toml"
    spec.write_text('images_topic = "/cam/compressed"\ncamera_joint = "pan"\nfov_deg = 60\n')
    api.import_bag(bag, tmp_path / "b.mcap", spec)
    sweep = api.open_log(tmp_path / "b.mcap").sweeps()[0]
    assert sweep.count == 4
    assert sweep.camera_angle_rad == pytest.approx(math.pi)
    assert sweep.fov_rad == pytest.approx(math.radians(60))


def test_the_camera_yaw_is_read_at_each_image_stamp(tmp_path: Path) -> None:
    def fill(b: BagWriter) -> None:
        b.joint(NS // 2, ["camera_yaw"], [0.3])  # before the sweep: the first image's
        for k in range(3):
            t = NS + k * NS // 5
            b.image(t, _jpeg(k))
            b.joint(t + NS // 10, ["camera_yaw"], [0.3 - 2 * math.pi * (k + 1) / 3])

    api.import_bag(write_bag(tmp_path / "bag", fill), tmp_path / "run.mcap")
    log = read_log(tmp_path / "run.mcap")
    from pipemap.recorder.schemas import SweepCommand

    angles = [
        SweepCommand.FromString(m.data).camera_angle_rad
        for m in log.messages
        if m.topic == Topic.SWEEP and SweepCommand.FromString(m.data).phase == SweepCommand.IMAGE
    ]
    assert angles == pytest.approx([0.3, 0.3 - 2 * math.pi / 3, 0.3 - 4 * math.pi / 3])


@pytest.mark.parametrize("encoding", ["mono8", "rgb8", "bgr8"])
def test_raw_images_are_read_in_each_encoding(tmp_path: Path, encoding: str) -> None:
    rng = np.random.default_rng(3)
    rgb = rng.integers(0, 256, (24, 32, 3), dtype=np.uint8)
    grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    pixels = {"mono8": grey, "rgb8": rgb, "bgr8": np.ascontiguousarray(rgb[:, :, ::-1])}[encoding]
    kind = "sensor_msgs/msg/Image"

    def fill(b: BagWriter) -> None:
        for k in range(2):
            t = NS + k * NS // 5
            b.joint(t, ["camera_yaw"], [-math.pi * k])
            message = STORE.types[kind](
                header=STORE.types["std_msgs/msg/Header"](
                    stamp=STORE.types["builtin_interfaces/msg/Time"](sec=t // NS, nanosec=t % NS),
                    frame_id="camera_link",
                ),
                height=24,
                width=32,
                encoding=encoding,
                is_bigendian=0,
                step=pixels.shape[1] * (1 if encoding == "mono8" else 3),
                data=pixels.reshape(-1),
            )
            b.write("/camera/image/compressed", kind, t, message)

    api.import_bag(write_bag(tmp_path / "bag", fill), tmp_path / "run.mcap")
    frames = api.open_log(tmp_path / "run.mcap").sweeps()[0].frames
    assert np.array_equal(frames[0], grey)


def test_optional_sensors_are_written_where_present(tmp_path: Path) -> None:
    def fill(b: BagWriter) -> None:
        _sweeps(b, [1.0])
        header = STORE.types["std_msgs/msg/Header"]
        time = STORE.types["builtin_interfaces/msg/Time"]
        for k in range(5):
            t = NS + k * NS // 10
            stamp = header(stamp=time(sec=t // NS, nanosec=t % NS), frame_id="base_link")
            for topic, value in (
                ("/range/front", 0.5),
                ("/range/left", 0.25),
                ("/range/right", 0.75),
            ):
                b.write(
                    topic,
                    "sensor_msgs/msg/Range",
                    t,
                    STORE.types["sensor_msgs/msg/Range"](
                        header=stamp,
                        radiation_type=1,
                        field_of_view=0.4,
                        min_range=0.0,
                        max_range=2.0,
                        range=value + k,
                    ),
                )
            v3 = STORE.types["geometry_msgs/msg/Vector3"]
            q = STORE.types["geometry_msgs/msg/Quaternion"]
            cov = np.zeros(9)
            b.write(
                "/imu",
                "sensor_msgs/msg/Imu",
                t,
                STORE.types["sensor_msgs/msg/Imu"](
                    header=stamp,
                    orientation=q(x=0, y=0, z=0, w=1),
                    orientation_covariance=cov,
                    angular_velocity=v3(x=0, y=0, z=0.1 * k),
                    angular_velocity_covariance=cov,
                    linear_acceleration=v3(x=1.0, y=-2.0, z=9.8),
                    linear_acceleration_covariance=cov,
                ),
            )
            pose = STORE.types["geometry_msgs/msg/PoseWithCovariance"](
                pose=STORE.types["geometry_msgs/msg/Pose"](
                    position=STORE.types["geometry_msgs/msg/Point"](x=k, y=2.0, z=0.0),
                    orientation=q(x=0, y=0, z=math.sin(0.25), w=math.cos(0.25)),
                ),
                covariance=np.zeros(36),
            )
            twist = STORE.types["geometry_msgs/msg/TwistWithCovariance"](
                twist=STORE.types["geometry_msgs/msg/Twist"](
                    linear=v3(x=0.2, y=0, z=0), angular=v3(x=0, y=0, z=0)
                ),
                covariance=np.zeros(36),
            )
            b.write(
                "/odom",
                "nav_msgs/msg/Odometry",
                t,
                STORE.types["nav_msgs/msg/Odometry"](
                    header=header(stamp=stamp.stamp, frame_id="odom"),
                    child_frame_id="base_link",
                    pose=pose,
                    twist=twist,
                ),
            )

    api.import_bag(write_bag(tmp_path / "bag", fill), tmp_path / "run.mcap")
    log = read_log(tmp_path / "run.mcap")
    assert log.counts[Topic.RANGES] == log.counts[Topic.IMU] == log.counts[Topic.CONTROLLER] == 5
    from pipemap.recorder.schemas import ControllerState, Imu, Ranges

    last = {m.topic: m.data for m in log.messages}
    ranges = Ranges.FromString(last[Topic.RANGES])
    assert (ranges.front_m, ranges.front_left_m, ranges.front_right_m) == (4.5, 4.25, 4.75)
    imu = Imu.FromString(last[Topic.IMU])
    assert imu.yaw_rate_rps == pytest.approx(0.4) and imu.accel_left_mps2 == -2.0
    state = ControllerState.FromString(last[Topic.CONTROLLER])
    assert (state.x_estimate_m, state.y_estimate_m) == (4.0, 2.0)
    assert state.heading_estimate_rad == pytest.approx(0.5)


# -- bad bags: one line naming the topic or message, exit 2 ------------------------------


def _bad(tmp_path: Path, capsys: pytest.CaptureFixture[str], fill, *extra: str) -> str:  # type: ignore[no-untyped-def]
    bag = write_bag(tmp_path / "bag", fill)
    status, out, err = _run(["import", str(bag), "-o", str(tmp_path / "run.mcap"), *extra], capsys)
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pipemap: error: "), err
    assert not (tmp_path / "run.mcap").exists()
    return lines[0]


def test_an_empty_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    line = _bad(tmp_path, capsys, lambda b: None)
    assert "the bag holds no messages" in line


def test_a_missing_camera_topic(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    line = _bad(tmp_path, capsys, lambda b: b.joint(NS, ["camera_yaw"], [0.0]))
    assert "/camera/image/compressed: no such topic" in line and "/joint_states" in line


def test_a_camera_topic_of_the_wrong_type(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def fill(b: BagWriter) -> None:
        b.joint(NS, ["camera_yaw"], [0.0])
        b.write(
            "/camera/image/compressed",
            "std_msgs/msg/String",
            NS,
            STORE.types["std_msgs/msg/String"](data="x"),
        )

    line = _bad(tmp_path, capsys, fill)
    assert "/camera/image/compressed: carries std_msgs/msg/String, not" in line


def test_an_optional_topic_of_the_wrong_type(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def fill(b: BagWriter) -> None:
        _sweeps(b, [1.0])
        b.write("/imu", "std_msgs/msg/String", NS, STORE.types["std_msgs/msg/String"](data="x"))

    assert "/imu: carries std_msgs/msg/String, not sensor_msgs/msg/Imu" in _bad(
        tmp_path, capsys, fill
    )


def test_no_camera_joint(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def fill(b: BagWriter) -> None:
        b.joint(NS, ["wheel_left", "wheel_right"], [0.0, 0.0])
        b.image(NS, _jpeg(0))

    line = _bad(tmp_path, capsys, fill)
    assert "/joint_states: no joint named 'camera_yaw' (joints: wheel_left, wheel_right)" in line


def test_images_of_mixed_sizes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def fill(b: BagWriter) -> None:
        _sweeps(b, [1.0])
        _sweeps(b, [10.0], size=(32, 24))

    line = _bad(tmp_path, capsys, fill)
    assert "/camera/image/compressed: image at 10.000 s is 32x24, the first is 64x48" in line


def test_an_image_that_does_not_decode(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def fill(b: BagWriter) -> None:
        _sweeps(b, [1.0])
        b.image(2 * NS, _jpeg(9)[:200])

    line = _bad(tmp_path, capsys, fill)
    assert "/camera/image/compressed: image at 2.000 s is a truncated or corrupt JPEG" in line


def test_a_sweep_that_does_not_turn_clockwise(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def fill(b: BagWriter) -> None:
        for k in range(4):
            b.joint(NS + k, ["camera_yaw"], [2 * math.pi * k / 4])
            b.image(NS + k, _jpeg(k))

    line = _bad(tmp_path, capsys, fill)
    assert "turns by +90.0 deg" in line and "not -90.0 (clockwise by 360/4)" in line


def test_a_message_that_does_not_decode(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    def fill(b: BagWriter) -> None:
        _sweeps(b, [1.0])
        b.raw("/imu", "sensor_msgs/msg/Imu", 3 * NS, b"\x00\x01\x00\x00\x01")

    line = _bad(tmp_path, capsys, fill)
    assert "/imu: message at 3.000 s does not decode as sensor_msgs/msg/Imu" in line


def test_not_a_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "folder").mkdir()
    status, _, err = _run(
        ["import", str(tmp_path / "folder"), "-o", str(tmp_path / "r.mcap")], capsys
    )
    assert status == 2 and "not a rosbag2 bag" in err
    status, _, err = _run(
        ["import", str(tmp_path / "nope"), "-o", str(tmp_path / "r.mcap")], capsys
    )
    assert status == 2 and "no such file or folder" in err


def test_a_bad_spec(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bag = write_bag(tmp_path / "bag", lambda b: _sweeps(b, [1.0]))
    for text, why in (
        ("colour = 1\n", "unknown key 'colour'"),
        ("sweep_gap_s = -1\n", "sweep_gap_s must be above 0"),
        ("images_topic = 3\n", "images_topic must be a string"),
        ("fov_deg = [\n", "not TOML"),
    ):
        (tmp_path / "spec.toml").write_text(text)
        status, _, err = _run(
            [
                "import",
                str(bag),
                "-o",
                str(tmp_path / "r.mcap"),
                "--spec",
                str(tmp_path / "spec.toml"),
            ],
            capsys,
        )
        assert status == 2 and why in err, err


@needs_sets
def test_a_bag_cut_short_keeps_its_whole_sweeps(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recorder killed part-way: the file stops inside a chunk. The sweeps before it
    are kept, the one it stops in is dropped, and the command says so (exit 0)."""
    folders = [
        PAPER_SETS / name for name in ("1", "4", "2", "10", "3", "1_noise", "2_noise", "3_noise")
    ]
    bag = sweep_bag(tmp_path / "bag", folders)
    storage = next(bag.glob("*.mcap"))
    data = storage.read_bytes()
    storage.write_bytes(data[: int(len(data) * 0.6)])
    status, out, err = _run(["import", str(bag), "-o", str(tmp_path / "run.mcap")], capsys)
    assert status == 0, err
    assert "cut short" in err and "was cut short after 1 image(s); dropped" in err
    assert "4 sweeps (24 images) in 4 visits" in out
    assert len(api.open_log(tmp_path / "run.mcap").sweeps()) == 4
    shutil.rmtree(bag)


def test_an_existing_log_is_replaced_only_with_force(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bag = write_bag(tmp_path / "bag", lambda b: _sweeps(b, [1.0]))
    (tmp_path / "run.mcap").write_bytes(b"earlier")
    status, _, err = _run(["import", str(bag), "-o", str(tmp_path / "run.mcap")], capsys)
    assert status == 2 and "refusing to overwrite without --force" in err
    assert (tmp_path / "run.mcap").read_bytes() == b"earlier"
    status, _, err = _run(["import", str(bag), "-o", str(tmp_path / "run.mcap"), "--force"], capsys)
    assert status == 0, err
    assert len(api.open_log(tmp_path / "run.mcap").sweeps()) == 1
