"""A log's trajectories in the TUM format, for evo (``pipemap export --tum``).

``estimated.tum`` is the robot's dead reckoning (``/robot/controller``: gyro heading,
encoder distance, in the start's frame), ``truth.tum`` the simulator's true pose
(``/truth/pose``, in the world frame; absent from a log without truth), one line per
pose: ``timestamp x y z qx qy qz qw``, the time in seconds of log time, the pose on
the pipe floor (z = 0, a rotation about z). The two frames differ by the start pose:
evo aligns them (``evo_ape tum truth.tum estimated.tum --align``).
``junctions.csv`` holds each visit's dead-reckoned position at its exit scan and,
where the log has truth, the junction it truly was.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from google.protobuf.message import DecodeError

from pipemap.errors import WriteError
from pipemap.recorder import schemas
from pipemap.recorder.reader import iter_log
from pipemap.recorder.topics import Topic

__all__ = ["TumResult", "export_tum", "tum_line"]

ESTIMATED = "estimated.tum"
TRUTH = "truth.tum"
JUNCTIONS = "junctions.csv"


@dataclass
class TumResult:
    """What was written: poses per file, junction rows."""

    folder: Path
    counts: dict[str, int] = field(default_factory=dict)


def tum_line(t_ns: int, x_m: float, y_m: float, yaw_rad: float) -> str:
    """One TUM pose: time in seconds, position, the quaternion of a yaw about z."""
    return (
        f"{t_ns // 1_000_000_000}.{t_ns % 1_000_000_000:09d} {x_m!r} {y_m!r} 0.0 "
        f"0.0 0.0 {math.sin(yaw_rad / 2)!r} {math.cos(yaw_rad / 2)!r}\n"
    )


def _yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def export_tum(log: str | Path, folder: str | Path) -> TumResult:
    """Write ``estimated.tum``, ``truth.tum`` (where the log has truth) and
    ``junctions.csv`` of the log ``log`` into ``folder`` (made if need be)."""
    estimated: list[str] = []
    truth: list[str] = []
    exits: dict[int, schemas.NodeEvent] = {}
    true_sweeps: dict[int, schemas.TrueSweep] = {}
    wanted = {Topic.CONTROLLER, Topic.TRUE_POSE, Topic.NODE, Topic.TRUE_SWEEP}
    with iter_log(log, wanted.__contains__) as stream:
        for m in stream:
            try:
                if m.topic == Topic.CONTROLLER:
                    s = schemas.ControllerState.FromString(m.data)
                    estimated.append(
                        tum_line(
                            m.log_time_ns, s.x_estimate_m, s.y_estimate_m, s.heading_estimate_rad
                        )
                    )
                elif m.topic == Topic.TRUE_POSE:
                    p = schemas.FrameTransform.FromString(m.data)
                    truth.append(
                        tum_line(m.log_time_ns, p.translation.x, p.translation.y, _yaw(p.rotation))
                    )
                elif m.topic == Topic.NODE:
                    event = schemas.NodeEvent.FromString(m.data)
                    if event.kind == schemas.NodeEvent.EXITS:
                        exits.setdefault(event.visit_id, event)
                elif m.topic == Topic.TRUE_SWEEP:
                    true = schemas.TrueSweep.FromString(m.data)
                    true_sweeps.setdefault(true.visit_id, true)
            except DecodeError:
                continue
    rows = io.StringIO()
    table = csv.writer(rows, lineterminator="\n")
    table.writerow(["visit", "x_m", "y_m", "odometer_m", "true_node", "true_x_m", "true_y_m"])
    for visit, event in sorted(exits.items()):
        true = true_sweeps.get(visit)
        table.writerow(
            [visit, repr(event.x_estimate_m), repr(event.y_estimate_m), repr(event.odometer_m)]
            + (["", "", ""] if true is None else [true.node, repr(true.x_m), repr(true.y_m)])
        )
    target = Path(folder)
    result = TumResult(target)
    files = {ESTIMATED: "".join(estimated), JUNCTIONS: rows.getvalue()}
    if truth:
        files[TRUTH] = "".join(truth)
    try:
        target.mkdir(exist_ok=True)
        for name, text in files.items():
            (target / name).write_text(text)
    except OSError as exc:
        raise WriteError(f"{target}: cannot write ({exc.strerror or exc})") from None
    result.counts = {ESTIMATED: len(estimated), TRUTH: len(truth), JUNCTIONS: len(exits)}
    return result
