""":mod:`pipemap.sweep_folders`: a run's records to image-set folders, without a world."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from pipemap.imagesets import load_image_set, read_info, read_robot_notes
from pipemap.recorder.convert import LogRecord, SweepDone
from pipemap.sim.episode import Pose
from pipemap.sim.stream import NodeArrival, NodeDeparture, NodeExits, SweepImage, SweepStart
from pipemap.sweep_folders import SweepFolders


def _sweep(
    sweep_id: int, visit_id: int, node: str, probe: tuple[str, float, float, float] | None
) -> list[LogRecord]:
    images = np.full((3, 16, 16, 3), 10 * sweep_id, np.uint8)
    return [
        SweepStart(0, sweep_id, visit_id, 3, 0.25, 1.0, probe),
        *(SweepImage(0, sweep_id, visit_id, j, 0.25, image) for j, image in enumerate(images)),
        SweepDone(0, sweep_id, visit_id, 3, Pose(1.0, 2.0, 0.05, yaw_rad=0.5), node),
    ]


def test_visits_are_written_once_left_with_their_notes_and_probes(tmp_path: Path) -> None:
    saver = SweepFolders(tmp_path, "even")
    saver(
        [
            NodeArrival(0, 1),
            *_sweep(1, 1, "S", None),
            *_sweep(2, 1, "S", ("yaw", 0.3, 0.0, 0.0)),  # a probe of active vision
            NodeExits(0, 1, (0.0, 1.5), 0.0, 0.0, 0.7),
        ]
    )
    assert not (tmp_path / "0001").exists()  # its departure may still come
    saver([NodeDeparture(0, 1, 2, 1.5), NodeArrival(0, 2), *_sweep(3, 2, "A", None)])
    visit = tmp_path / "0001"
    assert read_info(visit)["node"] == "S" and float(read_info(visit)["yaw"]) == 0.5
    notes = read_robot_notes(visit)
    assert notes.exits_rad == (0.0, 1.5) and notes.departure_rad == 1.5
    assert notes.odometer_m == 0.7 and notes.lighting == "even"
    assert load_image_set(visit).camera_angle_rad == 0.25
    probe = visit / "probes" / "yaw"
    assert load_image_set(probe).images.mean() == 20.0  # the probe's own images
    assert not (tmp_path / "0002").exists()
    saver.close()  # the run ended: the last visit is written too
    assert read_info(tmp_path / "0002")["node"] == "A"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["0001", "0002"]
