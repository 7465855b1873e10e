"""``pipemap batch`` for real: a small SPEC (2 networks x 2 seeds at 32 px, two
rules) through Ray on this machine, stopped with Ctrl-C and resumed; its table
against ``pipemap score`` on the same logs; the same SPEC on a real Ray head started
on a loopback port (``ray start --head``), whose results must equal the local ones;
and ``pipemap batch-report`` on the result."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import cv2
import pytest

from pipemap.batch import COLUMNS, SCORE_COLUMNS, VOLATILE_COLUMNS
from pipemap.batch.results import flatten_score
from pipemap.cli.app import main

# Two cheap worlds (3 and 5 visits at 32 px): these tests check the batch's table,
# signals, resume and cluster, not a network's outcome. Each run revisits a junction,
# so each group of the report has same-junction pairs to summarise.
SPEC = """\
[grid]
network = ["tree:2", "tree:3"]
seed = [0, 1]
condition = ["perfect"]
resolution = [32]
rule = ["default", "paper"]
"""
RUNS = 8


def pipemap(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args],
        capture_output=True,
        text=True,
        timeout=900,
        env=env,
    )


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _finished_runs(out: Path) -> list[Path]:
    runs = out / "runs"
    if not runs.is_dir():
        return []
    return [
        p for p in runs.iterdir() if not p.name.startswith(".") and (p / "result.json").exists()
    ]


@pytest.fixture(scope="module")
def spec(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "small.toml"
    path.write_text(SPEC)
    return path


def _stopped_batch(command: list[str], out: Path, stop: Callable[[int], None]) -> tuple[int, str]:
    """Runs ``command`` (a batch into ``out``) in a session of its own, calls ``stop``
    with its pid once a run has finished; returns its status and stderr."""
    # The batch starts with Ctrl-C's default action, as from a terminal: run from a
    # background job (`pytest &`), this process ignores SIGINT, and a child would
    # inherit that.
    batch = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=_default_sigint,
    )
    try:
        deadline = time.monotonic() + 600
        while not _finished_runs(out) and batch.poll() is None and time.monotonic() < deadline:
            time.sleep(0.2)
        if batch.poll() is None:
            stop(batch.pid)
        _, stderr = batch.communicate(timeout=120)
    finally:
        if batch.poll() is None:
            os.killpg(batch.pid, signal.SIGKILL)
            batch.wait()
    return batch.returncode, stderr


def _command(spec: Path, out: Path, *flags: str) -> list[str]:
    return [sys.executable, "-m", "pipemap", "batch", str(spec), "--out", str(out), *flags]


@pytest.fixture(scope="module")
def local(spec: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str, str]:
    """The SPEC run locally with its logs kept: interrupted by Ctrl-C once a run has
    finished, then resumed. Returns the folder and the two commands' stderr."""
    out = tmp_path_factory.mktemp("local") / "batch"
    # Ctrl-C as a terminal sends it: to the whole process group.
    status, interrupted = _stopped_batch(
        _command(spec, out, "--keep-logs"), out, lambda pid: os.killpg(pid, signal.SIGINT)
    )
    assert status == 130, interrupted
    assert "interrupted" in interrupted
    # One run at a time (the default is one per core): the summary says so.
    resumed = pipemap(
        "batch", str(spec), "--out", str(out), "--keep-logs", "--resume", "--workers", "1"
    )
    assert resumed.returncode == 0, resumed.stderr
    assert "; 1 workers, " in resumed.stdout
    return out, interrupted, resumed.stderr


def test_sigterm_stops_the_batch_as_ctrl_c_does_with_the_table_whole(
    spec: Path, tmp_path: Path
) -> None:
    # A scheduler's stop, or `kill`: SIGTERM to the batch's own process only. Ray's
    # driver handler would exit at once (status 1, a C++ stack dump) and leave the
    # table behind the finished runs.
    out = tmp_path / "batch"
    status, stopped = _stopped_batch(
        _command(spec, out), out, lambda pid: os.kill(pid, signal.SIGTERM)
    )
    assert status == 143, stopped
    assert "interrupted" in stopped and "SIGTERM received" not in stopped, stopped
    assert "Traceback" not in stopped, stopped
    finished = {p.name for p in _finished_runs(out)}
    assert 1 <= len(finished) < RUNS
    assert {r["run_id"] for r in _rows(out)} == finished


def _rows(out: Path) -> list[dict[str, str]]:
    with (out / "results.csv").open() as f:
        return list(csv.DictReader(f))


def test_ctrl_c_keeps_finished_runs_and_resume_makes_the_rest(
    local: tuple[Path, str, str],
) -> None:
    out, interrupted, resumed = local
    kept = int(resumed.split("; ")[1].split(" complete runs kept")[0])
    assert 1 <= kept < RUNS  # the runs finished before Ctrl-C were not made again
    assert f"{RUNS - kept} runs to make" in resumed
    rows = _rows(out)
    assert len(rows) == RUNS and all(r["status"] == "ok" for r in rows)
    assert not list((out / "runs").glob(".*"))  # no half-written run folder left
    again = pipemap("batch", str(out / "spec.toml"), "--out", str(out), "--resume")
    assert again.returncode == 0 and "0 runs to make" in again.stderr


def test_the_table_has_a_column_per_grid_key_and_per_score(local: tuple[Path, str, str]) -> None:
    out, _, _ = local
    rows = _rows(out)
    assert list(rows[0]) == list(COLUMNS)
    assert [(r["network"], r["seed"], r["rule"]) for r in rows] == [
        (n, s, rule) for n in ("tree:2", "tree:3") for s in "01" for rule in ("default", "paper")
    ]
    assert {r["resolution"] for r in rows} == {"32"} and {r["start"] for r in rows} == {"S"}
    table = json.loads((out / "results.json").read_text())
    assert table["runs_total"] == RUNS and len(table["runs"]) == RUNS
    assert table["rules"]["paper"]["flags"] == ["--rule", "paper"]
    first = table["runs"][0]
    assert isinstance(first["map_correct"], bool) and isinstance(first["seed"], int)


def _score_cli(*args: str) -> dict[str, object]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["score", *args, "--json"]) == 0
    doc: dict[str, object] = json.loads(out.getvalue())
    return doc


def test_the_table_is_what_pipemap_score_says_on_the_same_logs(
    local: tuple[Path, str, str],
) -> None:
    out, _, _ = local
    rows = _rows(out)
    # The two rules of a recording scored one log, kept once (linked).
    for a, b in zip(rows[::2], rows[1::2], strict=True):
        logs = [out / "runs" / r["run_id"] / "run.mcap" for r in (a, b)]
        assert logs[0].stat().st_ino == logs[1].stat().st_ino
    for row in rows:
        folder = out / "runs" / row["run_id"]
        result = json.loads((folder / "result.json").read_text())
        # The command the run folder names, run on its kept log.
        flags = row["rule_flags"].split()
        cli = _score_cli(str(folder / "run.mcap"), *flags, "--threshold", row["threshold"])
        assert result["commands"]["score"].startswith(" ".join(["pipemap score", *flags]))
        saved = json.loads((folder / "score.json").read_text())
        # Timing differs from one score to the next, but every latency column is there,
        # the phases of the mean among them, each within the mean.
        timed = {c: float(row[c]) for c in SCORE_COLUMNS if c.startswith("latency_ms.")}
        phases = [t for c, t in timed.items() if c.startswith("latency_ms.phases.")]
        assert len(phases) == 4 and min(timed.values()) >= 0.0
        assert sum(phases) <= timed["latency_ms.mean"] + 0.01
        for doc in (cli, saved):
            doc.pop("latency_ms")
            doc.pop("log")
        assert saved == cli
        flat = flatten_score(cli)
        # Every score is a column (latency was taken out above: it is timing; these runs
        # have no deposits, so no blocked pipes: tests/batch/test_real_conditions.py).
        assert set(flat) == {
            c for c in SCORE_COLUMNS if not c.startswith(("latency_ms", "blocked."))
        }
        assert all(row[c] == "" for c in SCORE_COLUMNS if c.startswith("blocked."))
        for column in SCORE_COLUMNS:
            if column.startswith(("latency_ms", "blocked.")):
                continue
            expected = flat[column]
            text = (
                ""
                if expected is None
                else str(expected).lower()
                if isinstance(expected, bool)
                else str(expected)
            )
            assert row[column] == text, (row["run_id"], column)


@pytest.fixture(scope="module")
def ray_head() -> Iterator[tuple[str, dict[str, str]]]:
    """A real Ray head on this machine, on a loopback port with its own token; stopped
    at the end, also when a test fails."""
    ray = shutil.which("ray") or str(Path(sys.executable).parent / "ray")
    tmp = Path(tempfile.mkdtemp(prefix="pmray-", dir="/tmp"))  # short: Ray's socket paths

    def free_port() -> int:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            return int(s.getsockname()[1])

    token = tmp / "token"
    token.write_text(os.urandom(32).hex())
    env = {
        **os.environ,
        "RAY_AUTH_MODE": "token",
        "RAY_AUTH_TOKEN_PATH": str(token),
        "RAY_USAGE_STATS_ENABLED": "0",
        "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER": "0",  # the head on 127.0.0.1, not the LAN
    }
    port = free_port()
    log = (tmp / "head.log").open("w")
    head = subprocess.Popen(
        [
            ray,
            "start",
            "--head",
            "--block",
            "--port",
            str(port),
            "--node-ip-address",
            "127.0.0.1",
            "--num-cpus",
            "2",
            "--include-dashboard",
            "false",
            "--disable-usage-stats",
            "--temp-dir",
            str(tmp / "ray"),
            "--ray-client-server-port",
            str(free_port()),
            "--dashboard-agent-listen-port",
            str(free_port()),
        ],
        stdout=log,
        stderr=subprocess.STDOUT,
        env=env,
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 120
        while "Ray runtime started" not in (tmp / "head.log").read_text():
            assert head.poll() is None, (tmp / "head.log").read_text()
            assert time.monotonic() < deadline, "the Ray head did not start in 120 s"
            time.sleep(0.2)
        yield f"127.0.0.1:{port}", env
    finally:
        # `ray stop` would stop every Ray of this machine: stop ours, by its process.
        head.send_signal(signal.SIGTERM)
        with contextlib.suppress(subprocess.TimeoutExpired):
            head.wait(timeout=60)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(head.pid, signal.SIGKILL)
        head.wait()
        log.close()
        shutil.rmtree(tmp, ignore_errors=True)


def test_a_ray_cluster_gives_the_local_results(
    spec: Path,
    local: tuple[Path, str, str],
    ray_head: tuple[str, dict[str, str]],
    tmp_path: Path,
) -> None:
    address, env = ray_head
    out = tmp_path / "cluster"
    done = pipemap("batch", str(spec), "--out", str(out), "--address", address, env=env)
    assert done.returncode == 0, done.stderr
    assert f"a Ray cluster at {address}" in done.stderr
    local_rows, cluster_rows = _rows(local[0]), _rows(out)
    assert len(cluster_rows) == RUNS
    for a, b in zip(local_rows, cluster_rows, strict=True):
        for column in COLUMNS:
            if column not in VOLATILE_COLUMNS:
                assert a[column] == b[column], (a["run_id"], column)


def test_batch_report_writes_grouped_tables_and_figures(local: tuple[Path, str, str]) -> None:
    out, _, _ = local
    done = pipemap("batch-report", str(out))
    assert done.returncode == 0, done.stderr
    text = (out / "report.md").read_text()
    assert "| network | rule | runs | failed | map correct |" in text
    assert "`pipemap score --rule paper`" in text
    assert "`pipemap score` (no flags)" in text
    doc = json.loads((out / "report.json").read_text())
    assert doc["by"] == ["network", "rule"] and len(doc["groups"]) == 4
    group = doc["groups"][0]
    assert group["runs"] == 2 and group["seeds"] == [0, 1]
    stat = group["metrics"]["pairs.same.mean"]
    assert stat["n"] == 2 and stat["min"] <= stat["mean"] <= stat["max"]
    for name in ("report_similarity.png", "report_rotation.png"):
        image = cv2.imread(str(out / name))
        assert image is not None and image.shape[2] == 3
    by_seed = pipemap("batch-report", str(out), "--by", "seed")
    assert by_seed.returncode == 0
    assert [g["group"] for g in json.loads((out / "report.json").read_text())["groups"]] == [
        {"seed": 0},
        {"seed": 1},
    ]
    bad = pipemap("batch-report", str(out), "--by", "colour")
    assert bad.returncode == 2 and bad.stderr.count("\n") == 1 and "not a grid key" in bad.stderr
