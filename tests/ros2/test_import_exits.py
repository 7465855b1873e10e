"""``pipemap import`` of a bag without pipemap's exit scans: each visit's exits worked
out from its raw ``sensor_msgs/msg/Range`` readings (docs/ros2.md, recorder/ros2_exits.py).

The bags are written by rosbags, not by pipemap; their ranges encode known exits,
for a robot that stands still while its camera turns (three rangers, three
directions) and for one that turns in place after its sweep (its yaw from
``/odom``, the front ranger seeing every direction).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pipemap import api
from pipemap.cli import main
from pipemap.recorder import Topic, read_log
from pipemap.recorder.schemas import NodeEvent
from tests.ros2.bags import NS, STORE, BagWriter, write_bag
from tests.ros2.test_import import _sweeps

WALL_M, OPEN_M = 0.08, 1.5


def _header(t_ns: int, frame: str) -> Any:
    time = STORE.types["builtin_interfaces/msg/Time"]
    return STORE.types["std_msgs/msg/Header"](
        stamp=time(sec=t_ns // NS, nanosec=t_ns % NS), frame_id=frame
    )


def _range(bag: BagWriter, topic: str, t_ns: int, range_m: float) -> None:
    kind = "sensor_msgs/msg/Range"
    message = STORE.types[kind](
        header=_header(t_ns, topic.rsplit("/", 1)[1]),
        radiation_type=1,
        field_of_view=0.1,
        min_range=0.01,
        max_range=2.0,
        range=range_m,
    )
    bag.write(topic, kind, t_ns, message)


def _odom(bag: BagWriter, t_ns: int, yaw: float) -> None:
    types = STORE.types
    q = types["geometry_msgs/msg/Quaternion"](x=0, y=0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))
    pose = types["geometry_msgs/msg/PoseWithCovariance"](
        pose=types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=0.0), orientation=q
        ),
        covariance=np.zeros(36),
    )
    v3 = types["geometry_msgs/msg/Vector3"]
    twist = types["geometry_msgs/msg/TwistWithCovariance"](
        twist=types["geometry_msgs/msg/Twist"](linear=v3(x=0, y=0, z=0), angular=v3(x=0, y=0, z=0)),
        covariance=np.zeros(36),
    )
    kind = "nav_msgs/msg/Odometry"
    message = types[kind](
        header=_header(t_ns, "odom"), child_frame_id="base_link", pose=pose, twist=twist
    )
    bag.write("/odom", kind, t_ns, message)


def _scans(log_path: Path) -> dict[int, list[float]]:
    """Each visit's exits as the log's EXITS events hold them."""
    out = {}
    for m in read_log(log_path).messages:
        if m.topic == Topic.NODE:
            event = NodeEvent.FromString(m.data)
            assert event.kind == NodeEvent.EXITS
            out[event.visit_id] = list(event.exits_rad)
    return out


def _close(found: list[float], expected: list[float], tolerance: float) -> bool:
    if len(found) != len(expected):
        return False
    return all(
        abs(math.remainder(f - e, 2.0 * math.pi)) < tolerance
        for f, e in zip(sorted(found), sorted(expected), strict=True)
    )


#: Front, left and right ranges at three junctions, and the exits they encode
#: (relative to the arrival heading, left positive; straight back always, unseen).
STILL = [
    ((OPEN_M, WALL_M, OPEN_M), [0.0, -math.pi / 2, math.pi]),  # straight on and right
    ((WALL_M, OPEN_M, OPEN_M), [math.pi / 2, -math.pi / 2, math.pi]),  # a T, left and right
    ((WALL_M, WALL_M, WALL_M), [math.pi]),  # a dead end
]


def test_a_robot_standing_still_gets_the_exits_its_three_rangers_see(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    starts = [1.0, 11.0, 21.0]

    def fill(bag: BagWriter) -> None:
        _sweeps(bag, starts)
        for start, ((front, left, right), _) in zip(starts, STILL, strict=True):
            # During the sweep (1 s) and 1 s after: the junction as it is.
            for k in range(20):
                t = int((start + 0.1 * k) * NS)
                for topic, value in (("front", front), ("left", left), ("right", right)):
                    _range(bag, f"/range/{topic}", t, value)
            # Driving off 5 s later, in a pipe: after the scan's window, not its readings.
            for k in range(30):
                t = int((start + 5.0 + 0.1 * k) * NS)
                for topic, value in (("front", OPEN_M), ("left", OPEN_M), ("right", OPEN_M)):
                    _range(bag, f"/range/{topic}", t, value)

    bag = write_bag(tmp_path / "bag", fill)
    status = main(["import", str(bag), "-o", str(tmp_path / "run.mcap")])
    out, err = capsys.readouterr()
    assert status == 0, err
    assert "the exits are worked out from the range readings" in err
    assert "the map has no ports" not in err
    scans = _scans(tmp_path / "run.mcap")
    assert sorted(scans) == [1, 2, 3]
    for visit, (_, expected) in enumerate(STILL, start=1):
        assert _close(scans[visit], expected, 1e-6), (visit, scans[visit])

    # The side rangers' mount is the spec's.
    spec = tmp_path / "spec.toml"
    spec.write_text("range_side_deg = 60.0\n")
    assert main(["import", str(bag), "-o", str(tmp_path / "60.mcap"), "--spec", str(spec)]) == 0
    sixty = math.radians(60.0)
    assert _close(_scans(tmp_path / "60.mcap")[2], [sixty, -sixty, math.pi], 1e-6)

    # The scan's window is the spec's: 8 s after the last image takes in the readings
    # of the pipe it drives off by (more of them than of the junction), open to the left.
    spec.write_text("exit_scan_s = 8.0\n")
    assert main(["import", str(bag), "-o", str(tmp_path / "8s.mcap"), "--spec", str(spec)]) == 0
    wide = _scans(tmp_path / "8s.mcap")[1]
    assert _close(wide, [0.0, math.pi / 2, -math.pi / 2, math.pi], 1e-6), wide

    # The replay's map has those ports: one per exit at each junction.
    assert main(["replay", str(tmp_path / "run.mcap"), "-o", str(tmp_path / "map.json")]) == 0
    capsys.readouterr()
    nodes = json.loads((tmp_path / "map.json").read_text())["nodes"]
    assert sorted(len(n["ports"]) for n in nodes) == [1, 3, 3]


def test_a_robot_turning_in_place_gets_its_exits_from_odometry(tmp_path: Path) -> None:
    # Exits straight on, 100 degrees to the left and back; the robot turns once round
    # (counter-clockwise, 2 s) after its sweep, reading its front ranger at 100 Hz.
    exits = [0.0, math.radians(100.0), math.pi]
    start = 1.0

    def fill(bag: BagWriter) -> None:
        _sweeps(bag, [start])
        turn_start = start + 1.0
        _odom(bag, int(start * NS), 0.3)  # the arrival heading: 0.3 rad in the odom frame
        for k in range(200):
            t = int((turn_start + 0.01 * k) * NS)
            heading = 2.0 * math.pi * k / 200
            _odom(bag, t, 0.3 + heading)
            near = min(abs(math.remainder(heading - e, 2.0 * math.pi)) for e in exits)
            _range(bag, "/range/front", t, OPEN_M if near < math.radians(20.0) else WALL_M)

    bag = write_bag(tmp_path / "bag", fill)
    api.import_bag(bag, tmp_path / "run.mcap")
    scans = _scans(tmp_path / "run.mcap")
    assert _close(scans[1], exits, math.radians(3.0)), scans

    # The opening threshold is the spec's: beyond every reading, no exit at all (the
    # scan looked back, so the way in is not added either).
    spec = tmp_path / "spec.toml"
    spec.write_text("exit_open_m = 2.0\n")
    assert main(["import", str(bag), "-o", str(tmp_path / "far.mcap"), "--spec", str(spec)]) == 0
    assert _scans(tmp_path / "far.mcap")[1] == []
