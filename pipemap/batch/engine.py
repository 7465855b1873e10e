"""Running a batch on Ray: this machine's cores, or an existing Ray cluster.

:func:`plan_batch` checks everything a batch needs (the output folder, the cluster's
address) without touching anything; :func:`run_batch` then runs the plan. Ray does
the scheduling: one task per recording (:func:`batch.run.run_recording`), handed to
Ray the costliest first, at most ``workers`` at a time, each retried once by Ray
when it raises or its worker dies, then recorded as failed with its reason while the
batch goes on. The driver (this
process) writes every finished run's folder as it arrives and rewrites the results
table, so an interrupted batch keeps every finished run and ``--resume`` starts
where it stopped.
"""

from __future__ import annotations

import contextlib
import functools
import ipaddress
import logging
import os
import re
import socket
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pipemap import __version__
from pipemap.allocator import keep_freed_memory
from pipemap.batch.folder import check_out, finished_results
from pipemap.batch.results import (
    RESULT_FILES,
    prepare_folder,
    result_row,
    write_recording,
    write_table,
)
from pipemap.batch.run import run_recording
from pipemap.batch.signals import held_signals, terminate_as_interrupt
from pipemap.batch.spec import BatchSpec, RunPoint
from pipemap.errors import InputError, Interrupted
from pipemap.stops import last_stop

__all__ = [
    "BatchEvent",
    "BatchOptions",
    "BatchPlan",
    "BatchSummary",
    "check_address",
    "plan_batch",
    "run_batch",
]

#: Files and folders of a batch that ``--force`` removes (nothing else in the folder).
BATCH_ENTRIES = ("runs", "spec.toml", *RESULT_FILES)
#: How long to wait for a cluster that answers on its port to accept this driver.
CONNECT_TIMEOUT_S = 60.0
#: How often the progress is refreshed while no run finishes.
TICK_S = 1.0
#: How often, at most, the results table is rewritten while runs finish (and at the end).
TABLE_S = 2.0


@dataclass(frozen=True)
class BatchOptions:
    """How to run a batch: where, how wide, and what to do with an existing folder."""

    address: str | None = None
    workers: int | None = None
    keep_logs: bool = False
    resume: bool = False
    force: bool = False
    #: Other files of the folder that ``force`` removes (a preset's own reports).
    extra_entries: tuple[str, ...] = ()


@dataclass(frozen=True)
class BatchPlan:
    """A checked batch: the SPEC, the folder, and the runs already complete there."""

    spec: BatchSpec
    out: Path
    options: BatchOptions
    complete: frozenset[str] = frozenset()

    @property
    def pending(self) -> tuple[RunPoint, ...]:
        """The runs still to make, in grid order."""
        return tuple(p for p in self.spec.points if p.run_id not in self.complete)


@dataclass(frozen=True)
class BatchEvent:
    """Something happened: a run finished (``ok``/``failed``), or time passed (``tick``)."""

    kind: str
    point: RunPoint | None
    doc: Mapping[str, Any] | None
    done: int
    total: int
    failed: int
    running: int
    elapsed_s: float

    @property
    def eta_s(self) -> float | None:
        """Time left at the pace so far (``None`` until a run of this session finished)."""
        return None if self.done <= 0 else self.elapsed_s / self.done * (self.total - self.done)


@dataclass
class BatchSummary:
    """How a batch went."""

    total: int
    skipped: int
    done: int = 0
    failed: int = 0
    interrupted: bool = False
    stop_signal: int = 0  #: the number of the signal that stopped it (0: Ctrl-C)
    workers: int = 0
    wall_s: float = 0.0
    #: CPU seconds the finished recordings took on their workers.
    cpu_s: float = 0.0
    rows: list[dict[str, Any]] = field(default_factory=list)


# ------------------------------------------------------------------- checking


def _parse_address(address: str) -> tuple[str, int]:
    m = re.fullmatch(r"\[?([^\[\]]+?)\]?:(\d{1,5})", address.strip())
    if m is None or not 0 < int(m.group(2)) < 65536:
        raise InputError(
            f"--address {address}: expected HOST:PORT, the address `ray start --head` "
            "prints (e.g. 127.0.0.1:6379)"
        )
    return m.group(1), int(m.group(2))


def check_address(address: str, timeout_s: float = 5.0) -> tuple[str, int]:
    """``HOST:PORT`` of a Ray head that answers, or :class:`InputError`."""
    host, port = _parse_address(address)
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as exc:
        reason = exc.strerror or type(exc).__name__
        raise InputError(
            f"--address {address}: no Ray head answers there ({reason.lower()}); "
            "start one with `ray start --head`"
        ) from None
    return host, port


def plan_batch(spec: BatchSpec, out: Path, options: BatchOptions) -> BatchPlan:
    """Check the output folder (with ``resume``, that it holds ``spec``'s runs) and the
    cluster's address; nothing is written."""
    if options.resume and options.force:
        raise InputError("--resume and --force: choose one")
    if options.workers is not None and options.workers < 1:
        raise InputError(f"--workers {options.workers}: must be at least 1")
    check_out(spec, out, options.resume, options.force)
    if options.address is not None:
        check_address(options.address)
    complete: set[str] = set()
    if options.resume and out.is_dir():
        found = finished_results(spec, out)
        complete = {run_id for run_id, doc in found.items() if doc["status"] == "ok"}
    return BatchPlan(spec, out, options, frozenset(complete))


# ------------------------------------------------------------------------ Ray


def _is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _quiet_ray(address: str | None) -> None:
    """Environment for Ray, set before it is imported (a user's own settings win)."""
    # No usage statistics sent anywhere.
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    if address is None or _is_loopback(_parse_address(address)[0]):
        # A cluster on this machine only: keep Ray on the loopback address (as Ray
        # does on macOS and Windows) rather than the machine's network address, so
        # that nothing listens beyond this machine and a head started with
        # `--node-ip-address 127.0.0.1` finds this driver on the same node.
        os.environ.setdefault("RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "0")


def _connect(address: str) -> None:
    import ray

    failure: list[BaseException] = []

    def connect() -> None:
        try:
            ray.init(
                address=address.strip(),
                log_to_driver=False,
                logging_level=logging.ERROR,
            )
        except BaseException as exc:  # reported by the caller, in one line
            failure.append(exc)

    thread = threading.Thread(target=connect, daemon=True)
    thread.start()
    thread.join(CONNECT_TIMEOUT_S)
    if thread.is_alive():
        raise InputError(
            f"--address {address}: a server answers but no Ray cluster took this driver "
            f"within {CONNECT_TIMEOUT_S:.0f} s (is it a Ray head of the same version?)"
        )
    if failure:
        exc = failure[0]
        text = str(exc).strip().splitlines()
        detail = text[0] if text else type(exc).__name__
        if "auth" in type(exc).__name__.lower() or "token" in str(exc).lower():
            detail = (
                "the cluster asks for its token: set RAY_AUTH_MODE=token (and "
                "RAY_AUTH_TOKEN_PATH if the token is not in ~/.ray/auth_token)"
            )
        raise InputError(f"--address {address}: cannot join the Ray cluster: {detail}")


def _cluster_cpus() -> int:
    import ray

    resources = ray.cluster_resources()  # type: ignore[no-untyped-call]
    return max(1, int(resources.get("CPU", 1)))


def _beside_installed_package() -> contextlib.chdir[str]:
    """Start Ray from the folder ``pipemap`` was imported from: Ray puts the driver's
    working folder first on its workers' path, where a checkout's ``pipemap/`` folder
    would shadow the installed package."""
    return contextlib.chdir(str(Path(__file__).resolve().parents[2]))


@contextlib.contextmanager
def ray_session(address: str | None, workers: int | None) -> Iterator[int]:
    """Ray started on this machine (``address`` ``None``) or joined at ``address``,
    shut down (or left) at the end; yields how many runs may go at once. An already
    initialised Ray (a test's) is used as it is and left running."""
    _quiet_ray(address)
    import ray

    if ray.is_initialized():
        yield workers or _cluster_cpus()
        return
    if address is None:
        cpus = workers or os.cpu_count() or 1
        with _beside_installed_package():
            ray.init(
                address="local",
                num_cpus=cpus,
                include_dashboard=False,
                log_to_driver=False,
                logging_level=logging.ERROR,
                # Results come back as soon as they are done; logs are tens of MB at most.
                object_store_memory=512 * 1024 * 1024,
            )
    else:
        with _beside_installed_package():
            _connect(address)
        cpus = workers or _cluster_cpus()
    try:
        yield cpus
    finally:
        ray.shutdown()


def _take_recording(
    out: Path,
    points: tuple[RunPoint, ...],
    outcome: Mapping[str, Any] | None,
    why: str,
    keep_logs: bool,
    summary: BatchSummary,
    rows: dict[str, dict[str, Any]],
    event: Callable[[str, RunPoint | None, Mapping[str, Any] | None], None],
) -> None:
    """Write a finished recording's runs and count them in ``summary`` and ``rows``,
    as one step: a stop waits for it, because the runs share the log and the table a
    stop writes must hold every run whose folder is written."""
    with held_signals():
        docs = write_recording(out, points, outcome, why, keep_logs)
        for point, doc in zip(points, docs, strict=True):
            if doc["status"] != "ok":
                summary.failed += 1
            rows[point.run_id] = result_row(out, doc)
            summary.done += 1
            event(doc["status"], point, doc)
        if outcome is not None:
            summary.cpu_s += float(outcome.get("cpu_s", 0.0))


def _interrupted(exc: BaseException) -> bool:
    """Whether a task failed because Ctrl-C reached its worker."""
    cause = getattr(exc, "cause", None)
    return isinstance(cause, KeyboardInterrupt) or "KeyboardInterrupt" in str(exc)


def _reason(exc: BaseException) -> str:
    """One line saying why a task failed, from what Ray raised."""
    import ray.exceptions

    deaths = tuple(
        getattr(ray.exceptions, name)
        for name in ("WorkerCrashedError", "NodeDiedError", "LocalRayletDiedError")
        if hasattr(ray.exceptions, name)
    )
    cause = exc
    if isinstance(exc, ray.exceptions.RayTaskError):
        inner = getattr(exc, "cause", None)
        if isinstance(inner, BaseException):
            cause = inner
    elif isinstance(exc, deaths):
        return "its worker died (twice: retried once)"
    lines = [line for line in str(cause).strip().splitlines() if line.strip()]
    text = lines[-1].strip() if lines else ""
    name = type(cause).__name__
    return f"{name}: {text}" if text else name


# ----------------------------------------------------------------------- running

#: The task: the runs of one recording -> their outcome (see batch.run).
Task = Callable[..., Mapping[str, Any]]


def _cost(points: tuple[RunPoint, ...]) -> float:
    """A rough guess of a recording's work, to hand out the long ones first (so that
    the batch does not end waiting on one long run): the autonomous robot drives
    between junctions; every run renders its sweeps."""
    p = points[0]
    drive = 3.0 if p.condition == "autonomous" else 1.0
    return drive + p.images * (p.resolution / 400.0) ** 2 + 0.5 * len(points)


def _recordings(points: tuple[RunPoint, ...]) -> list[tuple[RunPoint, ...]]:
    """The runs grouped by recording, the costliest first (ties in grid order)."""
    groups: dict[tuple[Any, ...], list[RunPoint]] = {}
    for p in points:
        groups.setdefault(p.recording_key, []).append(p)
    return sorted((tuple(g) for g in groups.values()), key=_cost, reverse=True)


def _one_thread(task: Task) -> Task:
    """``task`` with OpenCV held to one thread, and the worker's allocator set up as a
    command's is (:func:`pipemap.allocator.keep_freed_memory`).

    Each task has one core (``num_cpus=1``), and the others are busy with tasks of
    their own. Ray sets ``OMP_NUM_THREADS=1`` for that, but OpenCV's thread pool does
    not read it: it starts a thread per core of the machine, which then compete with
    the other tasks (two workers on 2 cores: the runs took 1.14 times the CPU they
    take one after another; 1.01 held to one). OpenCV's results do not depend on its
    threads: a log recorded so has the same bytes (``tests/recorder/test_inline.py``).
    """

    @functools.wraps(task)
    def on_one_thread(*args: Any, **kwargs: Any) -> Mapping[str, Any]:
        import cv2

        cv2.setNumThreads(1)
        keep_freed_memory()  # as the command line does (pipemap.allocator)
        return task(*args, **kwargs)

    return on_one_thread


def run_batch(
    plan: BatchPlan,
    progress: Callable[[BatchEvent], None] | None = None,
    task: Task = run_recording,
) -> BatchSummary:
    """Run every pending run of ``plan`` on Ray and write its folder and the table.

    Ctrl-C or SIGTERM stops the batch: running tasks are cancelled, every finished
    run stays and is in the table, and the summary says ``interrupted``.
    """
    _quiet_ray(plan.options.address)  # before Ray is imported: it reads them then
    import ray

    spec, out = plan.spec, plan.out
    pending = plan.pending
    summary = BatchSummary(total=len(spec.points), skipped=len(plan.complete))
    started = time.perf_counter()
    # Every finished run keeps its row, failed ones too until they are made again.
    rows: dict[str, dict[str, Any]] = {}
    if plan.options.resume and out.is_dir():
        for run_id, doc in finished_results(spec, out).items():
            rows[run_id] = result_row(out, doc)
    forced = (*BATCH_ENTRIES, *plan.options.extra_entries) if plan.options.force else ()
    prepare_folder(out, spec.text, forced)
    written = [0.0]

    def table(now: bool = False) -> list[dict[str, Any]]:
        """Rewrite the table, at most every TABLE_S unless ``now``."""
        if now or time.perf_counter() - written[0] >= TABLE_S:
            written[0] = time.perf_counter()
            return write_table(out, spec, rows.values(), __version__)
        return []

    def event(kind: str, point: RunPoint | None, doc: Mapping[str, Any] | None) -> None:
        if progress is not None:
            progress(
                BatchEvent(
                    kind,
                    point,
                    doc,
                    summary.done,
                    len(pending),
                    summary.failed,
                    len(running),
                    time.perf_counter() - started,
                )
            )

    def finished(points: tuple[RunPoint, ...], outcome: Mapping[str, Any] | None, why: str) -> None:
        _take_recording(out, points, outcome, why, plan.options.keep_logs, summary, rows, event)
        table()

    queue = _recordings(pending)
    running: dict[Any, tuple[RunPoint, ...]] = {}
    if not queue:  # nothing to make: no need for Ray
        summary.rows = table(now=True)
        return summary
    with (
        ray_session(plan.options.address, plan.options.workers) as workers,
        terminate_as_interrupt(),
    ):
        summary.workers = workers
        remote = ray.remote(num_cpus=1, max_retries=1, retry_exceptions=True)(_one_thread(task))
        keep = plan.options.keep_logs
        table(now=True)
        event("start", None, None)
        try:
            while queue or running:
                while queue and len(running) < workers:
                    points = queue.pop(0)
                    running[remote.remote(points, keep)] = points  # type: ignore[call-arg]
                ready, _ = ray.wait(list(running), num_returns=1, timeout=TICK_S)
                if not ready:
                    event("tick", None, None)
                    continue
                for ref in ready:
                    points = running.pop(ref)
                    try:
                        outcome = ray.get(ref)
                    except Exception as exc:  # a RayTaskError, a dead worker: recorded
                        if _interrupted(exc):  # Ctrl-C reached the worker too: not run
                            raise KeyboardInterrupt from exc
                        finished(points, None, _reason(exc))
                    else:
                        finished(points, outcome, "")
        except KeyboardInterrupt as exc:
            summary.stop_signal = exc.signum if isinstance(exc, Interrupted) else last_stop()
            # Not ray.cancel: cancelling a task as it completes can abort this process
            # (a Ray core check, seen with Ray 2.60). Shutting down ends the running
            # tasks (a cluster ends a driver's tasks when the driver leaves).
            summary.interrupted = True
        # Written before Ray shuts down, while a second SIGTERM is still ignored.
        summary.rows = table(now=True)
    summary.wall_s = time.perf_counter() - started
    return summary
