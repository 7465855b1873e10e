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

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pipemap.errors import InputError
from pipemap.imagesets import load_image_set, load_image_sets, read_robot_notes
from pipemap.localizer import (
    ImageSet,
    Localizer,
    LocalizerConfig,
    dumps_document,
    map_document,
)
from pipemap.recorder import Integrity
from pipemap.replay import (
    REPLAY_TOPICS,
    SCORE_TOPICS,
    FileSource,
    LoggedSweep,
    MessageSource,
    ReplayResult,
    ScoreReport,
    StreamSource,
    sweeps_of,
)
from pipemap.replay import replay as _replay
from pipemap.replay import score as _score

if TYPE_CHECKING:
    from pipemap.recorder import Progress, RecordResult, RecordSettings

#: ``pipemap -v`` prints each folder's decision (stderr).
_LOG = logging.getLogger(__name__)

__all__ = [
    "ImageSet",
    "Integrity",
    "Log",
    "LocalizerConfig",
    "LoggedSweep",
    "ReplayResult",
    "ScoreReport",
    "dumps_document",
    "load_image_set",
    "load_image_sets",
    "map_image_sets",
    "open_log",
    "record",
    "replay",
    "score",
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
    path = Path(path)
    return Log(path, FileSource(path))


def _source(log: Log | MessageSource | str | Path, topics: tuple[str, ...]) -> MessageSource:
    """The log to replay: a path is read as the replay goes (its ``topics`` only)."""
    if isinstance(log, Log):
        return log.source
    if isinstance(log, str | Path):
        return StreamSource(log, topics)
    return log


def replay(
    log: Log | MessageSource | str | Path,
    config: LocalizerConfig | None = None,
    progress: Callable[[int, int | None], None] | None = None,
    keep_images: bool = False,
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
    pair statistics) are kept either way.
    """
    return _replay(_source(log, REPLAY_TOPICS), config, progress, keep_sets=keep_images)


def score(
    log: Log | MessageSource | str | Path, config: LocalizerConfig | None = None
) -> ScoreReport:
    """Replay ``log`` and score its map against the log's ground truth (``/truth``)."""
    return _score(_source(log, SCORE_TOPICS), config)


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
    localizer = Localizer(config)
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
    return map_document(localizer.map, visits)


def record(
    path: str | Path,
    settings: RecordSettings,
    overwrite: bool = False,
    progress: Callable[[Progress], None] | None = None,
) -> RecordResult:
    """Simulate ``settings`` (network, seed, condition, ...) with the localizer online
    and write the whole run to the MCAP log ``path``.

    Without ``overwrite`` an existing file is never touched. Loads the simulator.
    """
    from pipemap import __version__
    from pipemap.recorder import record_run
    from pipemap.sim.network import build_network
    from pipemap.sim.world_budget import check_world_fits

    target = Path(path)
    if target.is_dir():
        raise InputError(f"{target}: is a folder, not a file")
    if target.exists() and not overwrite:
        raise InputError(f"{target}: exists; refusing to overwrite")
    if not target.parent.is_dir():
        raise InputError(f"{target}: folder {target.parent} does not exist")
    network = build_network(settings.network, seed=settings.seed)
    check_world_fits(network, settings.network)
    return record_run(target, settings, network, __version__, progress, overwrite)
