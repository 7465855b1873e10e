"""The batch engine on a real Ray started once for this module, with stand-in tasks:
a run that fails once is retried and kept, a run that always fails or whose worker
dies is recorded as failed with its reason, and the batch goes on."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import subprocess
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import pytest

from pipemap.batch import BatchOptions, parse_spec, plan_batch, run_batch
from pipemap.batch.engine import _quiet_ray
from pipemap.batch.spec import RunPoint
from pipemap.cli import main

SPEC = """
[grid]
network = ["paper"]
seed = [0, 1, 2, 3]
resolution = [32]
rule = ["default", "paper"]
"""
#: What a stand-in run does, by seed: 0 succeeds, 1 fails once, 2 always fails,
#: 3 kills its worker.
FLAKY, FAILING, DYING = 1, 2, 3


@pytest.fixture(scope="module")
def ray_here() -> Iterator[None]:
    """Ray on this machine, once for the module (the engine uses it as it is)."""
    _quiet_ray(None)
    import ray

    ray.init(
        address="local",
        num_cpus=2,
        include_dashboard=False,
        log_to_driver=False,
        object_store_memory=128 * 1024 * 1024,
    )
    yield
    ray.shutdown()


def _score(points: Sequence[RunPoint]) -> dict[str, Any]:
    score = {
        "log": "run.mcap",
        "map_correct": True,
        "visits": 2,
        "decisions": {"correct_known": 0, "correct_new": 2, "false_merge": 0, "false_new": 0},
    }
    return {
        p.run_id: {
            "score_json": json.dumps(score),
            "visits_csv": "visit\n",
            "pairs": {"same": [], "different": [0.1], "rotation_error_rad": []},
            "known_rotation_errors_rad": [],
            "score_wall_s": 0.0,
        }
        for p in points
    }


#: A folder counting attempts; set by the test before the function is sent to Ray's
#: workers, which get it with the function (pickled by value).
MARKS = ""


def stand_in(points: Sequence[RunPoint], keep_log: bool) -> dict[str, Any]:
    """A run by seed (see above)."""
    marks = MARKS
    seed = points[0].seed
    attempt = Path(marks) / f"seed{seed}-{os.getpid()}-{len(list(Path(marks).iterdir()))}"
    attempt.touch()
    tries = len(list(Path(marks).glob(f"seed{seed}-*")))
    if seed == FLAKY and tries == 1:
        raise RuntimeError("flaky: first attempt fails")
    if seed == FAILING:
        raise ValueError(f"broken run, attempt {tries}")
    if seed == DYING:
        os._exit(3)
    return {
        "record": {
            "run_status": "complete",
            "run_ok": True,
            "sweeps": 2,
            "simulated_s": 1.0,
            "record_wall_s": 0.0,
        },
        "runs": _score(points),
        "log": b"log" if keep_log else None,
        "wall_s": 0.0,
        "cpu_s": 0.5,
        "worker": f"test:{os.getpid()}",
        "pipemap_version": "test",
    }


def test_failures_are_retried_once_then_recorded(ray_here: None, tmp_path: Path) -> None:
    global MARKS
    from ray import cloudpickle

    cloudpickle.register_pickle_by_value(__import__(__name__))  # workers cannot import tests
    marks = tmp_path / "marks"
    marks.mkdir()
    MARKS = str(marks)
    spec = parse_spec(SPEC, "engine.toml")
    out = tmp_path / "out"
    plan = plan_batch(spec, out, BatchOptions(keep_logs=True))
    events: list[Any] = []
    task = stand_in
    summary = run_batch(plan, events.append, task=task)

    assert summary.total == 8 and summary.done == 8 and summary.failed == 4
    assert not summary.interrupted
    with (out / "results.csv").open() as f:
        rows = {int(r["seed"]): r for r in csv.DictReader(f) if r["rule"] == "paper"}
    assert rows[0]["status"] == "ok" and rows[0]["map_correct"] == "true"
    assert rows[FLAKY]["status"] == "ok"  # failed once, retried by Ray, kept
    assert len(list(marks.glob("seed1-*"))) == 2
    assert rows[FAILING]["status"] == "failed"
    assert rows[FAILING]["reason"] == "ValueError: broken run, attempt 2"  # after one retry
    assert len(list(marks.glob("seed2-*"))) == 2
    assert rows[DYING]["status"] == "failed" and "worker died" in rows[DYING]["reason"]
    assert rows[DYING]["map_correct"] == ""
    # Each run's folder: whole, the log kept for the runs that made one.
    assert (out / "runs" / rows[0]["run_id"] / "run.mcap").read_bytes() == b"log"
    failed = json.loads((out / "runs" / rows[FAILING]["run_id"] / "result.json").read_text())
    assert failed["status"] == "failed" and failed["commands"]["record"].startswith("pipemap")
    kinds = [e.kind for e in events if e.kind in ("ok", "failed")]
    assert sorted(kinds) == ["failed"] * 4 + ["ok"] * 4
    done = [e.done for e in events if e.kind in ("ok", "failed")]
    assert done == list(range(1, 9))
    assert events[-1].eta_s == 0.0

    # --resume makes the failed runs again, and keeps the complete ones.
    for path in marks.iterdir():
        path.unlink()
    plan = plan_batch(spec, out, BatchOptions(resume=True))
    assert len(plan.complete) == 4 and {p.seed for p in plan.pending} == {FAILING, DYING}
    summary = run_batch(plan, None, task=task)
    assert summary.skipped == 4 and summary.done == 4 and summary.failed == 4
    assert {p.name.split("-")[0] for p in marks.iterdir()} == {"seed2", "seed3"}
    table = json.loads((out / "results.json").read_text())
    assert table["runs_finished"] == 8 and table["runs_failed"] == 4

    # A resume stopped while its runs go keeps every finished run's row, the failed
    # ones too (their folders are still there): the table is as it was.
    before = (out / "results.csv").read_bytes()

    def stop(event: Any) -> None:
        if event.kind == "tick":
            raise KeyboardInterrupt

    plan = plan_batch(spec, out, BatchOptions(resume=True))
    summary = run_batch(plan, stop, task=sleeper)
    (marks / "release").touch()
    assert summary.interrupted and summary.done == 0
    assert (out / "results.csv").read_bytes() == before
    assert json.loads((out / "results.json").read_text())["runs_finished"] == 8

    # Resuming it with another SPEC is refused, the folder untouched.
    other = out.parent / "other.toml"
    other.write_text(SPEC.replace("[0, 1, 2, 3]", "[0, 1]"))
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = main(["batch", str(other), "--out", str(out), "--resume"])
    assert code == 2 and err.getvalue().count("\n") == 1, err.getvalue()
    assert "seed (0, 1, 2, 3 there; 0, 1 here)" in err.getvalue()
    assert (out / "results.csv").read_bytes() == before
    assert (out / "spec.toml").read_text() == SPEC


def sleeper(points: Sequence[RunPoint], keep_log: bool) -> dict[str, Any]:
    """A run that is still going when the batch is stopped; it ends when the test
    releases it (the test's Ray outlives the batch, and its cores are shared)."""
    import time

    release = Path(MARKS) / "release"
    for _ in range(1200):
        if release.exists():
            break
        time.sleep(0.1)
    raise RuntimeError("released")


def threads_reported(points: Sequence[RunPoint], keep_log: bool) -> dict[str, Any]:
    """A run that succeeds and says, as its worker, how many threads OpenCV has."""
    import cv2

    return {**stand_in(points, keep_log), "worker": f"cv2-threads={cv2.getNumThreads()}"}


def test_a_batch_task_keeps_opencv_to_its_one_core(ray_here: None, tmp_path: Path) -> None:
    """Each task has one core: OpenCV's thread pool, which starts a thread per core of
    the machine whatever Ray says, is held to one thread in a batch's task."""
    global MARKS
    from ray import cloudpickle

    cloudpickle.register_pickle_by_value(__import__(__name__))
    marks = tmp_path / "marks"
    marks.mkdir()
    MARKS = str(marks)

    # The premise: a process as Ray starts a worker (OMP_NUM_THREADS=1) gets more.
    # (Not asked of a Ray worker: one that ran a batch's task before keeps its one.)
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    code = "import cv2; print(cv2.getNumThreads())"
    plain = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
    assert int(plain.stdout) > 1
    spec = parse_spec(SPEC.replace("[0, 1, 2, 3]", "[0]"), "threads.toml")
    out = tmp_path / "out"
    run_batch(plan_batch(spec, out, BatchOptions()), None, task=threads_reported)
    workers = {json.loads(p.read_text())["worker"] for p in out.glob("runs/*/result.json")}
    assert workers == {"cv2-threads=1"}
