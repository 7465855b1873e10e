"""Shared fixtures: the paper's own image sets, from ``../shared/paper_imagesets``."""

from __future__ import annotations

import contextlib
import fcntl
import math
import os
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from pipemap.imagesets import load_image_set, read_info
from pipemap.localizer import ImageSet

REPO = Path(__file__).resolve().parents[1]
PAPER_SETS = Path(
    os.environ.get("PIPEMAP_PAPER_IMAGESETS", REPO.parent / "shared" / "paper_imagesets")
)
#: Two sets show the same junction when their recorded x, y are this close (README there).
SAME_JUNCTION_M = 0.15


@dataclass(frozen=True)
class PaperSet:
    """One of the paper's image sets with its recorded camera pose (ground truth)."""

    name: str
    path: Path
    images: ImageSet
    x_m: float
    y_m: float
    yaw_rad: float

    def same_junction(self, other: PaperSet) -> bool:
        return math.hypot(self.x_m - other.x_m, self.y_m - other.y_m) < SAME_JUNCTION_M


@pytest.fixture(scope="session")
def paper_sets() -> dict[str, PaperSet]:
    """Every set of the shared folder, by folder name (sorted)."""
    if not PAPER_SETS.is_dir():
        pytest.fail(f"the paper's image sets are missing: {PAPER_SETS}")
    out = {}
    for path in sorted(p for p in PAPER_SETS.iterdir() if p.is_dir()):
        info = read_info(path)
        out[path.name] = PaperSet(
            path.name,
            path,
            load_image_set(path),
            float(info["x"]),
            float(info["y"]),
            float(info["yaw"]),
        )
    assert len(out) >= 11, f"expected the 11 shared sets, found {sorted(out)}"
    return out


@pytest.fixture(scope="session")
def recorded_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An autonomous run of ``paper`` at 64 px, recorded once for the session: in a
    parallel run (``pytest -n N``), once for all the workers, in the folder their own
    temporary folders share (the first worker to need it records it, the others wait
    for it under a lock). Tests only read it."""
    from tests.logs import record

    if not os.environ.get("PYTEST_XDIST_WORKER"):
        path = tmp_path_factory.mktemp("recorded") / "run.mcap"
        done = record(path)
        assert done.returncode == 0, done.stderr
        return path
    folder = tmp_path_factory.getbasetemp().parent / "recorded"
    folder.mkdir(exist_ok=True)
    path, finished = folder / "run.mcap", folder / "finished"
    with held_lock(folder / "lock"):
        if not finished.exists():
            path.unlink(missing_ok=True)  # what a worker that failed left
            done = record(path)
            assert done.returncode == 0, done.stderr
            finished.touch()
    return path


# ------------------------------------------------------------ parallel runs (xdist)
#: Test modules that start Ray: a local cluster in the test process, a batch or an
#: experiment as a subprocess, or a head with ``ray start``. Under ``pytest -n N`` no
#: two of them run at once: two local clusters started together on one machine race
#: for Ray's session folder in /tmp/ray, and each holds an object store of its own.
#: (xdist's ``xdist_group`` cannot say this with pytest 9.2: xdist 3.8 marks a group
#: by rewriting the test's node id, which pytest 9.2 no longer reads back; see
#: pytest-dev/pytest-xdist#1386.)
RAY_MODULES = frozenset(
    {
        "tests/batch/test_batch_ray.py",
        "tests/batch/test_engine.py",
        "tests/test_experiment.py",
        "tests/test_packaging.py",
    }
)


def ray_lock(module: str) -> Path | None:
    """The file whose lock a worker of this ``pytest -n`` run holds while it runs
    ``module`` (a path from the checkout's root), if the module is one of
    :data:`RAY_MODULES`; None for other modules and in a serial run."""
    run = os.environ.get("PYTEST_XDIST_TESTRUNUID")
    if not os.environ.get("PYTEST_XDIST_WORKER") or not run or module not in RAY_MODULES:
        return None
    return Path(tempfile.gettempdir()) / f"pipemap-tests-ray-{run}.lock"


@contextlib.contextmanager
def held_lock(path: Path) -> Iterator[None]:
    """An exclusive lock on ``path`` (created if need be), waited for, held while the
    block runs; the system frees it if the process dies."""
    with path.open("a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


@pytest.fixture(scope="module", autouse=True)
def _ray_alone(request: pytest.FixtureRequest) -> Iterator[None]:
    """In a parallel run, a module of :data:`RAY_MODULES` runs while no other does.
    Autouse and module-scoped, it is set up before the module's own fixtures (the
    ones that start Ray) and torn down after them. Run with ``--dist loadscope``, a
    module's tests all go to one worker, so its fixtures start Ray once."""
    lock = ray_lock(request.path.relative_to(REPO).as_posix())
    if lock is None:
        yield
        return
    with held_lock(lock):
        yield


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: object) -> object:
    """``--dist loadscope`` hands its units out slowest first, the modules that start
    Ray one at a time (tests/schedule.py); other modes are xdist's own."""
    if config.getvalue("dist") != "loadscope":
        return None
    from tests.schedule import SlowestFirst

    return SlowestFirst(config, log, exclusive=RAY_MODULES)
