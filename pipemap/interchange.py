"""A run's data in and out of other tools' formats: ROS 2 bags (``pipemap import`` and
``export --ros2``), TUM trajectories for evo, GeoJSON for GIS tools and a replay's
results as a log Foxglove shows. :mod:`pipemap.api` exports every function here."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from pipemap.api import Log, _new_file, replay
from pipemap.localizer import LocalizerConfig

if TYPE_CHECKING:
    from pipemap.recorder.ros2_contract import BagSpec
    from pipemap.recorder.ros2_export import ExportResult
    from pipemap.recorder.ros2_import import ImportResult
    from pipemap.recorder.trajectory import TumResult
    from pipemap.replay import MessageSource, ReplayResult


def import_bag(
    bag: str | Path,
    output: str | Path,
    spec: BagSpec | str | Path | None = None,
    overwrite: bool = False,
) -> ImportResult:
    """Read the ROS 2 bag ``bag`` (a rosbag2 folder or storage file, MCAP or SQLite,
    CDR) and write it as the pipemap log ``output``, which ``replay``, ``score`` and
    ``view`` take. ``spec`` (a :class:`~pipemap.recorder.ros2_contract.BagSpec`, or
    the path of a TOML file of its keys) says which topics are read; docs/ros2.md is
    the contract. Everything is checked before the log is written; without
    ``overwrite`` an existing file is never touched. Needs ``pipemap[ros]``."""
    from pipemap.recorder.ros2_contract import BagSpec, load_spec
    from pipemap.recorder.ros2_import import import_bag as _import_bag

    target = _new_file(output, overwrite)
    if not isinstance(spec, BagSpec):
        spec = load_spec(spec)
    from pipemap import __version__

    return _import_bag(bag, target, spec, __version__)


def ros2_available() -> None:
    """Raise an :class:`InputError` saying how to install rosbags where it is missing
    (reading and writing bags needs it)."""
    from pipemap.recorder.ros2_bag import typestore

    typestore()


def export_ros2(log: str | Path, output: str | Path, overwrite: bool = False) -> ExportResult:
    """Write the pipemap log ``log`` as a ROS 2 bag: the rosbag2 folder ``output``
    (metadata.yaml, MCAP storage, CDR) with the run's images, camera joint, IMU,
    ranges, wheel odometry, ``/tf`` and sweep markers (docs/ros2.md). ``pipemap
    import`` reads it back to a log that replays to the same map. Without
    ``overwrite`` an existing folder is never touched. Needs ``pipemap[ros]``."""
    from pipemap.recorder.ros2_export import export_ros2 as _export_ros2

    return _export_ros2(log, output, overwrite)


def export_tum(log: str | Path, folder: str | Path) -> TumResult:
    """Write the log's dead-reckoned (``estimated.tum``) and true (``truth.tum``)
    trajectories in the TUM format that evo reads, and each visit's junction
    position (``junctions.csv``), into ``folder``."""
    from pipemap.recorder.trajectory import export_tum as _export_tum

    return _export_tum(log, folder)


def save_results_log(
    result: ReplayResult, output: str | Path, threshold: float | None = None
) -> dict[str, int]:
    """Write a replay's results as an MCAP log that Foxglove shows: the estimated pose
    per visit (``foxglove.PoseInFrame`` on ``/replay/pose``, and ``/tf``), the map as
    it grows (``foxglove.SceneUpdate``) and the decisions (``pipemap.Decision``);
    see :mod:`pipemap.replay.results_log`. Returns the messages per topic."""
    from pipemap.replay.results_log import write_results_log

    return write_results_log(
        result, output, LocalizerConfig().threshold if threshold is None else threshold
    )


def export_geojson(
    log: Log | MessageSource | str | Path,
    output: str | Path,
    config: LocalizerConfig | None = None,
) -> int:
    """Replay ``log`` and write its map as GeoJSON for GIS tools: junctions as points
    placed by the robot's dead reckoning, pipes as lines with their ports and driven
    lengths, in a local metric frame the file names (:mod:`pipemap.replay.geojson`).
    ``log`` may instead be a map document's path (``.json``, as ``pipemap replay -o``
    writes it): its junctions are then placed by chaining its ports and pipe lengths.
    Returns the features written."""
    from pipemap.replay.geojson import read_map_document, write_geojson

    if isinstance(log, str | Path) and Path(log).suffix == ".json":
        return write_geojson(read_map_document(log), output, Path(log).stem)
    name = Path(log).stem if isinstance(log, str | Path) else "pipemap"
    return write_geojson(replay(log, config), output, name)
