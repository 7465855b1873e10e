"""A replay's results as an MCAP log that Foxglove shows (``pipemap replay --save-log``).

Per decided visit, at the log time its sweep ended:

* ``/replay/pose`` (``foxglove.PoseInFrame``, frame ``map``) and ``/tf``
  (``foxglove.FrameTransform``, ``map`` -> ``base_link_estimate``): where the localizer
  puts the robot, at the junction it decided the visit was. A junction is placed where
  the robot's dead reckoning was at the exit scan of its first visit, so a recognised
  revisit snaps back to that place (the loop closed) however far the dead reckoning has
  drifted. The orientation is not estimated (identity). A log without exit scans has no
  positions, and so no poses.
* ``/replay/map`` (``foxglove.SceneUpdate``): the map so far, each junction a sphere
  with its id, each pipe travelled a line between the junctions it joins.
* ``/replay/decision`` (``pipemap.Decision``): the decision, as ``/online/decision``.
"""

from __future__ import annotations

from pathlib import Path

from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from mcap_protobuf.writer import Writer

from pipemap.errors import WriteError
from pipemap.recorder.messages import decision_message, labelled_sphere, timestamp
from pipemap.recorder.schemas import FrameTransform
from pipemap.replay.replayer import ReplayResult

__all__ = ["RESULT_TOPICS", "junction_places", "write_results_log"]

POSE, TF, MAP, DECISION = "/replay/pose", "/tf", "/replay/map", "/replay/decision"
RESULT_TOPICS = (POSE, TF, MAP, DECISION)
MAP_FRAME, ESTIMATE_FRAME = "map", "base_link_estimate"


def _map_update(
    t_ns: int, places: dict[int, tuple[float, float]], pipes: set[tuple[int, int]]
) -> SceneUpdate:
    update = SceneUpdate()
    stamp = timestamp(t_ns)
    for node, xy in sorted(places.items()):
        update.entities.append(
            labelled_sphere(
                t_ns, MAP_FRAME, f"node/{node}", xy, 0.1, Color(g=0.7, a=1.0), str(node)
            )
        )
    for a, b in sorted(pipes):
        if a not in places or b not in places:
            continue
        entity = SceneEntity(timestamp=stamp, frame_id=MAP_FRAME, id=f"pipe/{a}-{b}")
        (ax, ay), (bx, by) = places[a], places[b]
        entity.lines.append(
            LinePrimitive(
                type=LinePrimitive.Type.LINE_STRIP,
                pose=Pose(position=Vector3(), orientation=Quaternion(w=1.0)),
                thickness=0.03,
                points=[Point3(x=ax, y=ay), Point3(x=bx, y=by)],
                color=Color(r=0.6, g=0.6, b=0.6, a=1.0),
            )
        )
        update.entities.append(entity)
    return update


def junction_places(result: ReplayResult) -> dict[int, tuple[float, float]]:
    """Each junction's place: the robot's dead reckoning at the exit scan of the
    junction's first visit that has one (junctions without one are left out)."""
    places: dict[int, tuple[float, float]] = {}
    for visit in result.visits:
        if visit.exits is not None and visit.exits.exits_rad is not None:
            places.setdefault(visit.decision.node, (visit.exits.x_m, visit.exits.y_m))
    return places


def write_results_log(result: ReplayResult, output: str | Path, threshold: float) -> dict[str, int]:
    """Write ``result`` to the MCAP file ``output``; returns the messages per topic."""
    counts = dict.fromkeys(RESULT_TOPICS, 0)
    every_place = junction_places(result)
    places: dict[int, tuple[float, float]] = {}
    pipes: set[tuple[int, int]] = set()
    breaks = set(result.breaks)
    previous: int | None = None
    try:
        with open(output, "wb") as stream:
            writer = Writer(stream)
            for k, visit in enumerate(result.visits):
                t, node = visit.time_ns, visit.decision.node
                if node in every_place:
                    places.setdefault(node, every_place[node])
                if previous is not None and k not in breaks and previous != node:
                    pipes.add((min(previous, node), max(previous, node)))
                previous = node
                writes = [
                    (DECISION, decision_message(t, visit.visit_id, visit.decision, threshold))
                ]
                if node in places:
                    x, y = places[node]
                    writes.append(
                        (
                            POSE,
                            PoseInFrame(
                                timestamp=timestamp(t),
                                frame_id=MAP_FRAME,
                                pose=Pose(
                                    position=Vector3(x=x, y=y), orientation=Quaternion(w=1.0)
                                ),
                            ),
                        )
                    )
                    writes.append(
                        (
                            TF,
                            FrameTransform(
                                timestamp=timestamp(t),
                                parent_frame_id=MAP_FRAME,
                                child_frame_id=ESTIMATE_FRAME,
                                translation=Vector3(x=x, y=y),
                                rotation=Quaternion(w=1.0),
                            ),
                        )
                    )
                writes.append((MAP, _map_update(t, places, pipes)))
                for topic, message in writes:
                    writer.write_message(topic, message, log_time=t, publish_time=t)
                    counts[topic] += 1
            writer.finish()  # type: ignore[no-untyped-call]
    except OSError as exc:
        raise WriteError(f"{output}: cannot write ({exc.strerror or exc})") from None
    return counts
