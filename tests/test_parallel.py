"""The suite runs in parallel (``pytest -n auto --dist loadscope``, the README's
Quick start): the modules that start Ray take turns, through a file lock that one
worker holds at a time (tests/conftest.py)."""

from __future__ import annotations

import fcntl
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import RAY_MODULES, REPO, held_lock, ray_lock

#: What a test module that starts Ray itself contains.
STARTS_RAY = ("ray.init(", '"--head"')


def test_every_module_that_starts_ray_is_listed() -> None:
    for module in RAY_MODULES:
        assert (REPO / module).is_file(), f"{module} is listed but gone"
    for path in sorted((REPO / "tests").rglob("test_*.py")):
        module = path.relative_to(REPO).as_posix()
        if path != Path(__file__).resolve() and any(s in path.read_text() for s in STARTS_RAY):
            assert module in RAY_MODULES, f"{module} starts Ray: list it in RAY_MODULES"


def test_a_ray_module_locks_only_in_a_parallel_run(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    monkeypatch.setenv("PYTEST_XDIST_TESTRUNUID", "abc123")
    assert ray_lock("tests/test_experiment.py") is None  # serial: nothing to wait for
    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw1")
    lock = ray_lock("tests/test_experiment.py")
    assert lock is not None and lock.name == "pipemap-tests-ray-abc123.lock"
    assert ray_lock("tests/batch/test_engine.py") == lock  # one lock for all of them
    assert ray_lock("tests/localizer/test_ports.py") is None  # no Ray, no turn to wait


def _locked(path: Path) -> bool:
    with path.open("a") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
        fcntl.flock(f, fcntl.LOCK_UN)
        return False


def test_the_lock_keeps_another_worker_waiting_until_it_is_released(tmp_path: Path) -> None:
    lock = tmp_path / "ray.lock"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            "import sys; from pathlib import Path; from tests.conftest import held_lock\n"
            "with held_lock(Path(sys.argv[1])):\n"
            "    print('held', flush=True); sys.stdin.read()\n",
            str(lock),
        ],
        cwd=REPO,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "held\n"
        assert _locked(lock)
    finally:
        holder.communicate("", timeout=120)
    assert holder.returncode == 0
    assert not _locked(lock)
    with held_lock(lock):  # and this process can take it now
        assert lock.exists()
