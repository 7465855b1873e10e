"""pipemap from Python: record a run, open a log, replay it, score it, map image sets.

The command line is a thin layer over these functions; a script or a notebook uses
them directly::

    from pipemap import api

    log = api.open_log("run.mcap")
    print(log.metadata["network"], len(log.sweeps()), "sweeps")
    result = api.replay(log)                  # the map, rebuilt from /robot alone
    report = api.score(log)                   # against the log's /truth
    print(report.map_correct, report.counts())

Every function raises a :class:`pipemap.errors.PipemapError` subclass for bad input
(a missing file, a log that is not pipemap's, an unknown network), with a message
that names the offending value. Heavy modules (the simulator) load only when a
function needs them.
"""

from __future__ import annotations

import importlib
import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pipemap.errors import InputError
from pipemap.imagesets import lamp_lit, load_image_set, load_image_sets, read_robot_notes
from pipemap.localizer import (
    FastConfig,
    ImageSet,
    Localizer,
    LocalizerConfig,
    PreparedSet,
    SetMatch,
    dumps_document,
    map_document,
    normalised,
    pairwise_matches,
    prepare_for_pairs,
    reference_match,
)

if TYPE_CHECKING:
    from pipemap.interchange import (
        export_geojson,
        export_ros2,
        export_tum,
        import_bag,
        save_results_log,
    )
    from pipemap.localizer import RouteStep, TopoMap
    from pipemap.recorder import (
        Explore,
        Integrity,
        Progress,
        RecordResult,
        RecordSettings,
        RunObserver,
    )
    from pipemap.recorder.ros2_contract import BagSpec
    from pipemap.recorder.ros2_export import ExportResult
    from pipemap.recorder.ros2_import import ImportResult
    from pipemap.recorder.trajectory import TumResult
    from pipemap.replay import (
        FileSource,
        LoggedSweep,
        MessageSource,
        ReplayResult,
        ScoreReport,
    )
    from pipemap.replay.info import log_info
    from pipemap.routes import load_map, route, route_document
    from pipemap.sim.episode import Condition
    from pipemap.viewing import Viewed, view

#: Names of this module loaded on first use (PEP 562): the image-set commands never
#: read a log (loading mcap, protobuf and the replay cost ``pipemap match`` 0.18 s of
#: CPU, docs/performance.md), and what :func:`record` takes and returns pulls in the
#: simulator (``pipemap[sim]``), which reading, replaying and scoring do without.
_LAZY = {
    "Integrity": "pipemap.recorder",
    "LoggedSweep": "pipemap.replay",
    "MessageSource": "pipemap.replay",
    "ReplayResult": "pipemap.replay",
    "ScoreReport": "pipemap.replay",
    "BagSpec": "pipemap.recorder.ros2_contract",
    "ImportResult": "pipemap.recorder.ros2_import",
    "ExportResult": "pipemap.recorder.ros2_export",
    "TumResult": "pipemap.recorder.trajectory",
    "Condition": "pipemap.sim.episode",
    "Explore": "pipemap.recorder.online",
    "Progress": "pipemap.recorder.session",
    "RecordResult": "pipemap.recorder.session",
    "RecordSettings": "pipemap.recorder.settings",
    "RunObserver": "pipemap.recorder.session",
    # A map document's routes (``pipemap route``) and a log's description (``info``).
    "RouteStep": "pipemap.localizer",
    "TopoMap": "pipemap.localizer",
    "load_map": "pipemap.routes",
    "route": "pipemap.routes",
    "route_document": "pipemap.routes",
    "log_info": "pipemap.replay.info",
    # ROS 2 bags, TUM trajectories, GeoJSON and Foxglove results in and out.
    "import_bag": "pipemap.interchange",
    "ros2_available": "pipemap.interchange",
    "export_ros2": "pipemap.interchange",
    "export_tum": "pipemap.interchange",
    "save_results_log": "pipemap.interchange",
    "export_geojson": "pipemap.interchange",
    "view": "pipemap.viewing",
    "Viewed": "pipemap.viewing",
}


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module 'pipemap.api' has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


#: ``pipemap -v`` prints each folder's decision (stderr).
_LOG = logging.getLogger(__name__)

__all__ = [
    "Condition",
    "Explore",
    "ImageSet",
    "Integrity",
    "Log",
    "LocalizerConfig",
    "LoggedSweep",
    "MessageSource",
    "Progress",
    "RecordResult",
    "RecordSettings",
    "ReplayResult",
    "RunObserver",
    "ScoreReport",
    "BagSpec",
    "ImportResult",
    "ExportResult",
    "TumResult",
    "FastConfig",
    "SetMatch",
    "dumps_document",
    "export_geojson",
    "export_ros2",
    "export_tum",
    "import_bag",
    "load_image_set",
    "load_image_sets",
    "map_image_sets",
    "match_image_sets",
    "open_log",
    "record",
    "replay",
    "save_results_log",
    "score",
    "simulate",
    "RouteStep",
    "TopoMap",
    "load_map",
    "log_info",
    "route",
    "route_document",
    "view",
    "Viewed",
]


@dataclass(frozen=True)
class Log:
    """An opened pipemap log: its run settings, its integrity and its sweeps.

    Opening reads the file once; replaying or scoring the same :class:`Log` again
    does not read it again.
    """

    path: Path
    source: FileSource

    @property
    def metadata(self) -> dict[str, str]:
        """The run's settings as recorded (``pipemap.run``: network, seed, condition, ...)."""
        return self.source.run_metadata()

    @property
    def integrity(self) -> Integrity:
        """Whether the log is complete, cut short or damaged."""
        return self.source.integrity

    @property
    def problem(self) -> str | None:
        """What is wrong with a log that is not complete; ``None`` for a complete one."""
        return self.source.problem

    def sweeps(self) -> list[LoggedSweep]:
        """Every complete camera sweep of the log, in the robot's order: visits first
        taken at each junction and the probe sweeps of active vision (``probe`` set).
        Each holds the grey :class:`ImageSet` the localizer sees."""
        from pipemap.replay import sweeps_of

        return sweeps_of(self.source.robot_messages(), self.source.name).sweeps

    def visits(self) -> list[LoggedSweep]:
        """The sweeps that are junction visits (no probe sweeps), in the robot's order."""
        return [s for s in self.sweeps() if s.probe is None]


def open_log(path: str | Path) -> Log:
    """Open the pipemap log at ``path`` (an MCAP file written by ``pipemap record``).

    A log cut short or damaged opens too: :attr:`Log.integrity` says so, and what
    is intact replays. Raises :class:`pipemap.errors.LogFormatError` for a file
    that is missing or is not a pipemap log.
    """
    from pipemap.replay import FileSource

    path = Path(path)
    return Log(path, FileSource(path))


def _source(log: Log | MessageSource | str | Path, topics: tuple[str, ...]) -> MessageSource:
    """The log to replay: a path is read as the replay goes (its ``topics`` only)."""
    if isinstance(log, Log):
        return log.source
    if isinstance(log, str | Path):
        from pipemap.replay import StreamSource

        return StreamSource(log, topics)
    return log


def replay(
    log: Log | MessageSource | str | Path,
    config: LocalizerConfig | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    keep_images: bool = False,
    keep_prepared: bool = True,
    recorded_threshold: bool | None = None,
) -> ReplayResult:
    """Rebuild the map of ``log`` with a new localizer, from its ``/robot`` topics only.

    The same log and settings always give the same map document
    (``result.document()``). ``config`` defaults to pipemap's defaults;
    :data:`pipemap.localizer.PAPER` is the paper's rule. ``progress`` is called with
    the visits decided so far and their total, ``None`` until the log has been read.

    Each visit's images are dropped once it is decided, so a long log's replay holds
    its map, not its images (a 400 px sweep is 938 KiB: 2 GB for 2 000 visits);
    ``log.visits()`` gives them again on demand. ``keep_images`` keeps them, for
    ``result.visit_sets``. The visits as the matcher prepared them (83 KiB each, for
    pair statistics) are kept unless ``keep_prepared`` is false. With
    ``recorded_threshold`` the threshold is the one the log was recorded with, as
    ``pipemap replay`` and ``score`` take it without ``--threshold``; left ``None``,
    it is so when no ``config`` is given (a script's ``replay(log)`` and the command
    ``pipemap replay LOG`` build the same map) and ``config``'s threshold otherwise.
    """
    from pipemap.replay import REPLAY_TOPICS
    from pipemap.replay import replay as _replay

    source = _source(log, REPLAY_TOPICS)
    return _replay(
        source, config, progress, keep_images, keep_prepared, recorded_threshold=recorded_threshold
    )


def score(
    log: Log | MessageSource | str | Path,
    config: LocalizerConfig | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    recorded_threshold: bool | None = None,
) -> ScoreReport:
    """Replay ``log`` and score its map against the log's ground truth (``/truth``);
    ``progress`` and ``recorded_threshold`` as :func:`replay` takes them. The replay's notes are in
    ``report.replay_notes``, what of the truth could not be read in
    ``report.truth_notes``."""
    from pipemap.replay import SCORE_TOPICS
    from pipemap.replay import score as _score

    return _score(_source(log, SCORE_TOPICS), config, progress, recorded_threshold)


def match_image_sets(
    folders: Sequence[str | Path],
    config: FastConfig | None = None,
    fov_rad: float | None = None,
    keep_top_fraction: float | None = None,
    every_offset: bool = False,
    reference: bool = False,
    lamp: bool | None = None,
) -> dict[tuple[int, int], SetMatch]:
    """The paper's similarity (Algorithm 2) of every pair ``(i, j)``, ``i < j``, of
    image-set folders: what ``pipemap match`` prints.

    The fast path (:func:`pipemap.localizer.pairwise_matches` with ``config``) keeps
    of each folder only what the matcher needs (:func:`pipemap.localizer.prepare_for_pairs`),
    made as it is read: 25 sets of 800 px images are 384 MB as images, about 1 MB
    each so prepared. ``reference`` compares the images themselves with the paper's
    recipe at full resolution (:func:`pipemap.localizer.reference_match`; seconds a
    pair). Every folder is read and checked before any pair is compared. ``lamp``:
    normalise each image's illumination first, as the localizer does a lamp-lit
    camera's (``None``: when the folders' ``sweep.txt`` say they were lamp-lit).
    The fast path refines the offsets a screen on smaller images finds promising
    (``pairwise_matches``'s ``screen``); ``every_offset`` refines them all.
    """
    lit = lamp_lit(folders) if lamp is None else lamp
    illumination = LocalizerConfig().illumination
    if reference:
        sets = load_image_sets([str(f) for f in folders], fov_rad, keep_top_fraction)
        if lit:
            sets = [normalised(s, illumination) for s in sets]
        return {
            (i, j): reference_match(sets[i], sets[j])
            for i in range(len(sets))
            for j in range(i + 1, len(sets))
        }
    fast = config if config is not None else FastConfig()
    prepared: list[PreparedSet] = []
    first: tuple[str, ImageSet] | None = None
    for folder in folders:
        image_set = load_image_set(folder, fov_rad, keep_top_fraction)
        if first is None:
            first = (str(folder), image_set)
        elif image_set.images.shape != first[1].images.shape:
            raise InputError(
                f"{folder}: {image_set.count} images of {image_set.width}x"
                f"{image_set.height}, but {first[0]} has {first[1].count} of "
                f"{first[1].width}x{first[1].height}"
            )
        if lit:
            image_set = normalised(image_set, illumination)
        prepared.append(prepare_for_pairs(image_set, fast, every_offset))
    return pairwise_matches(prepared, fast, every_offset=every_offset, screen=True)


def map_image_sets(
    folders: Sequence[str | Path],
    config: LocalizerConfig | None = None,
    fov_rad: float | None = None,
    keep_top_fraction: float | None = None,
) -> dict[str, Any]:
    """The map of image-set folders (the paper's layout) taken as a visit sequence.

    Returns the document ``pipemap map --json`` prints: ``nodes``, ``edges`` and
    one ``visits`` entry per folder, in order. ``fov_rad`` and ``keep_top_fraction``
    default to the camera of the paper (80 degrees, the top half of each image). A
    folder's ``sweep.txt`` with the robot's exits (``pipemap sim --save-sweeps``
    writes them) gives the map ports.
    """
    if not folders:
        raise InputError("no image-set folders given")
    sets = load_image_sets([str(f) for f in folders], fov_rad, keep_top_fraction)
    # A lamp-lit camera's sweeps are normalised, as a replay does, unless said otherwise.
    localizer = Localizer((config or LocalizerConfig()).for_camera(lamp_lit(folders)))
    visits = []
    for name, image_set in zip(folders, sets, strict=True):
        # The robot's notes of an autonomous run's sweep (``sweep.txt``) give ports.
        notes = read_robot_notes(name)
        decision = localizer.localize(image_set, None, notes.exits_rad, notes.odometer_m)
        visits.append((str(name), decision))
        if _LOG.isEnabledFor(logging.DEBUG):
            _LOG.debug("%s: %s", name, decision.describe())
        if notes.departure_rad is not None:
            localizer.depart(notes.departure_rad)
    return map_document(localizer.map, visits, localizer.open_visits)


def _new_file(path: str | Path, overwrite: bool) -> Path:
    """``path`` as a file to write: not a folder, in a folder that exists, and not
    there already unless ``overwrite``."""
    target = Path(path)
    if target.is_dir():
        raise InputError(f"{target}: is a folder, not a file")
    if target.exists() and not overwrite:
        raise InputError(f"{target}: exists; refusing to overwrite")
    if not target.parent.is_dir():
        raise InputError(f"{target}: folder {target.parent} does not exist")
    return target


def record(
    path: str | Path,
    settings: RecordSettings,
    overwrite: bool = False,
    progress: Callable[[Progress], None] | None = None,
    observer: RunObserver | None = None,
    inline: bool = False,
) -> RecordResult:
    """Simulate ``settings`` (network, seed, condition, ...) with the localizer online
    and write the whole run to the MCAP log ``path``.

    Without ``overwrite`` an existing file is never touched. ``observer`` sees every
    record as the log gets it (``pipemap record --view`` streams them to rerun);
    ``inline`` writes the log in this process instead of a writer process (a batch's
    workers do): the same bytes either way. Loads the simulator (``pipemap[sim]``).
    """
    from pipemap import __version__
    from pipemap.recorder import record_run
    from pipemap.sim.network import build_network
    from pipemap.sim.world_budget import check_world_fits

    target = _new_file(path, overwrite)
    network = build_network(settings.network, seed=settings.seed)
    check_world_fits(network, settings.network, settings.world_memory_mib)
    return record_run(target, settings, network, __version__, progress, overwrite, observer, inline)


def simulate(
    folder: str | Path,
    settings: RecordSettings,
    overwrite: bool = False,
    progress: Callable[[Progress], None] | None = None,
) -> RecordResult:
    """Run ``settings`` as :func:`record` does, the same episode on the same seed, but
    write no log: each junction visit's sweep goes to ``folder`` as ``0001``, ``0002``,
    ... in the paper's image-set layout (:mod:`pipemap.sweep_folders`), which
    :func:`map_image_sets` maps. ``folder`` is made if need be; sweep folders of an
    earlier run in it are refused, or replaced with ``overwrite``. Loads the
    simulator (``pipemap[sim]``)."""
    from pipemap import __version__
    from pipemap.recorder import record_run
    from pipemap.sim.network import build_network
    from pipemap.sim.world_budget import check_world_fits
    from pipemap.sweep_folders import SweepFolders, clear_earlier_sweeps, earlier_sweeps

    target = Path(folder)
    if target.is_dir() and earlier_sweeps(target) and not overwrite:
        raise InputError(f"{target}: holds the sweeps of an earlier run; refusing to replace them")
    network = build_network(settings.network, seed=settings.seed)
    check_world_fits(network, settings.network, settings.world_memory_mib)
    if settings.start is not None and settings.start not in network.labels:
        raise InputError(
            f"--start {settings.start}: no such node in {settings.network} "
            f"({', '.join(network.labels)})"
        )
    settings.deposits(network)  # too many for the network: an error before any work
    clear_earlier_sweeps(target)
    saver = SweepFolders(target, "lamp" if settings.lamp_strength > 0.0 else "even")
    try:
        return record_run(None, settings, network, __version__, progress, observer=saver)
    finally:
        saver.close()
