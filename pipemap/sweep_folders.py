"""A run's sweeps as image-set folders in the paper's layout (``pipemap sim``).

:class:`SweepFolders` watches a run as a recording's observer does
(:data:`pipemap.recorder.RunObserver`) and writes each junction visit's sweep as
``DIR/0001``, ``DIR/0002``, ... in visit order: ``camera_image1..N.png``, ``info.txt``
with the camera pose at the sweep start and the true node, and ``sweep.txt`` with
what the robot noted (its camera angle, exits, departure, odometer, lighting), so
that ``pipemap map DIR/*`` maps the run as a replay of its log would. A probe sweep
of active vision goes to ``DIR/NNNN/probes/<kind>/``, inside its visit's folder, so
it is not a visit itself.

A visit's folder is written once the robot has left it (its exits and departure
are then known), or when the run ends: whatever ends the run, the visits swept so
far are kept.
"""

from __future__ import annotations

import re
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from pipemap.errors import WriteError
from pipemap.imagesets import RobotNotes, write_image_set
from pipemap.recorder.convert import LogRecord, SweepDone
from pipemap.sim.episode import Pose
from pipemap.sim.stream import NodeArrival, NodeDeparture, NodeExits, SweepImage, SweepStart

__all__ = ["SweepFolders", "clear_earlier_sweeps", "earlier_sweeps"]

#: The folders of one run's sweeps: ``0001``, ``0002``, ...
_SWEEP_FOLDER = re.compile(r"\d{4}")


def earlier_sweeps(folder: Path) -> list[str]:
    """The sweep folders (``0001``, ...) an earlier run left in ``folder``."""
    found = (p.name for p in folder.iterdir() if p.is_dir())
    return sorted(name for name in found if _SWEEP_FOLDER.fullmatch(name))


def clear_earlier_sweeps(target: Path) -> None:
    """Make ``target``, less any sweep folders of an earlier run, so that
    ``pipemap map DIR/*`` sees this run's alone (other files are left)."""
    try:
        target.mkdir(parents=True, exist_ok=True)
        for name in earlier_sweeps(target):
            shutil.rmtree(target / name)
    except OSError as exc:
        raise WriteError(f"{target}: {exc.strerror or exc}") from None


def _info(pose: Pose, node: str) -> dict[str, str]:
    """``info.txt`` of the paper's layout: the camera pose at the sweep start, the node."""
    info = {"cam_joint_pos": ""}
    for key in ("x", "y", "z", "roll", "pitch", "yaw"):
        name = f"{key}_m" if key in "xyz" else f"{key}_rad"
        info[key] = repr(float(getattr(pose, name)))
    info["node"] = node
    return info


@dataclass
class _Sweep:
    start: SweepStart
    images: list[np.ndarray] = field(default_factory=list)
    done: SweepDone | None = None


@dataclass
class _Visit:
    sweep: _Sweep | None = None
    probes: list[_Sweep] = field(default_factory=list)
    notes: RobotNotes = field(default_factory=RobotNotes)


class SweepFolders:
    """Writes a run's sweeps under ``target`` as they come (see the module)."""

    def __init__(self, target: Path, lighting: str | None) -> None:
        self.target = target
        self.lighting = lighting
        self.written = 0
        self._sweeps: dict[int, _Sweep] = {}
        self._visits: dict[int, _Visit] = {}

    def __call__(self, records: Sequence[LogRecord]) -> None:
        for record in records:
            self._take(record)

    def _take(self, record: LogRecord) -> None:
        if isinstance(record, SweepStart):
            self._sweeps[record.sweep_id] = _Sweep(record)
        elif isinstance(record, SweepImage):
            self._sweeps[record.sweep_id].images.append(record.image)
        elif isinstance(record, SweepDone):
            sweep = self._sweeps.pop(record.sweep_id)
            sweep.done = record
            visit = self._visits.setdefault(record.visit_id, _Visit())
            if sweep.start.probe is None:
                visit.sweep = sweep
            else:
                visit.probes.append(sweep)
        elif isinstance(record, NodeExits):
            visit = self._visits.setdefault(record.visit_id, _Visit())
            visit.notes = RobotNotes(record.exits_rad, None, record.odometer_m)
        elif isinstance(record, NodeDeparture):
            visit = self._visits.setdefault(record.visit_id, _Visit())
            visit.notes = replace(visit.notes, departure_rad=record.exit_rad)
        elif isinstance(record, NodeArrival):
            # Every earlier visit is complete: the robot has left it.
            self._write(lambda visit_id: visit_id < record.visit_id)

    def close(self) -> None:
        """The run has ended: write every visit not written yet."""
        self._write(lambda visit_id: True)

    def _write(self, due: Callable[[int], bool]) -> None:
        for visit_id in sorted(self._visits):
            if not due(visit_id):
                continue
            visit = self._visits.pop(visit_id)
            if visit.sweep is None:
                continue  # the run ended before this visit's sweep did
            self.written += 1
            folder = self.target / f"{self.written:04d}"
            notes = replace(visit.notes, lighting=self.lighting)
            self._save(folder, visit.sweep, notes)
            for probe in visit.probes:
                assert probe.start.probe is not None
                self._save(folder / "probes" / probe.start.probe[0], probe, None)

    @staticmethod
    def _save(folder: Path, sweep: _Sweep, notes: RobotNotes | None) -> None:
        assert sweep.done is not None
        info = _info(sweep.done.start_pose, sweep.done.true_node)
        images = np.stack(sweep.images)
        write_image_set(folder, images, info, sweep.start.camera_angle_rad, notes)
