"""Outputs are written whole or not at all (``pipemap.wholefile``): a disk that fills
while a command writes is one line and exit status 3, and leaves no part of a file
under the asked name (an earlier file stays as it was) and no temporary file beside
it. The full disk is the file size limit (``ulimit -f``, RLIMIT_FSIZE), which needs
no mount and no privilege: a write past it fails with EFBIG as one past a full disk
fails with ENOSPC.
"""

from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

from pipemap.sim import world
from tests.conftest import REPO

LOG = REPO / "recordings" / "paper_active.mcap"


def _limited(
    limit_bytes: int, *args: str, tmpdir: Path | None = None
) -> subprocess.CompletedProcess[str]:
    """``pipemap ARGS`` with files limited to ``limit_bytes`` (and TMPDIR set)."""

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    env = {key: value for key, value in os.environ.items() if key != "RUST_LOG"}
    if tmpdir is not None:
        env["TMPDIR"] = str(tmpdir)
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args],
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=limit,
        env=env,
    )


def _one_error_line(done: subprocess.CompletedProcess[str], *needles: str) -> str:
    assert done.returncode == 3, done.stderr
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr
    assert lines[0].startswith("pipemap: error: "), lines
    for needle in needles:
        assert needle in lines[0], lines
    return lines[0]


def test_a_map_that_does_not_fit_leaves_the_earlier_one_whole(tmp_path: Path) -> None:
    target = tmp_path / "map.json"
    target.write_text('{"earlier": true}\n')
    done = _limited(4096, "replay", str(LOG), "-o", str(target), "--force")
    _one_error_line(done, f"{target}: cannot write (File too large)")
    assert target.read_text() == '{"earlier": true}\n'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["map.json"]


def test_results_that_do_not_fit_leave_no_half_written_json(tmp_path: Path) -> None:
    folder = tmp_path / "results"
    done = _limited(4096, "score", str(LOG), "--save-results", str(folder))
    _one_error_line(done, "score.json: cannot write (File too large)")
    assert list(tmp_path.iterdir()) == []  # the folder it made is gone again


def test_results_are_saved_both_or_neither(tmp_path: Path) -> None:
    # Earlier results, and a visits.csv that cannot be replaced (a folder of that name):
    # score.json is written first, but must not be renamed into place without it.
    folder = tmp_path / "results"
    folder.mkdir()
    (folder / "score.json").write_text("earlier\n")
    (folder / "visits.csv").mkdir()
    done = _limited(1 << 30, "score", str(LOG), "--save-results", str(folder), "--force")
    _one_error_line(done, "visits.csv: cannot write (Is a directory)")
    assert (folder / "score.json").read_text() == "earlier\n"
    assert sorted(p.name for p in folder.iterdir()) == ["score.json", "visits.csv"]


def test_a_set_of_files_that_does_not_fit_leaves_none(tmp_path: Path) -> None:
    # write_all under a file size limit that the first file fits and the second does not.
    script = (
        "import resource, signal, sys\n"
        "from pathlib import Path\n"
        "from pipemap.errors import WriteError\n"
        "from pipemap.wholefile import write_all\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))\n"
        "signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
        "folder = Path(sys.argv[1])\n"
        "try:\n"
        "    write_all({folder / 'score.json': 'x' * 500, folder / 'visits.csv': 'y' * 5000})\n"
        "except WriteError as exc:\n"
        "    print(exc)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path)], capture_output=True, text=True, timeout=120
    )
    assert done.stderr == ""
    assert done.stdout.strip() == f"{tmp_path / 'visits.csv'}: cannot write (File too large)"
    assert list(tmp_path.iterdir()) == []


def test_a_view_that_does_not_fit_is_exit_3_and_leaves_nothing(tmp_path: Path) -> None:
    target = tmp_path / "view.rrd"
    done = _limited(100_000, "view", str(LOG), "--save", str(target))
    # pipemap's line alone: rerun's file writer logs its failure itself unless told not to.
    _one_error_line(done, f"{target}: cannot write (rerun: ")
    assert list(tmp_path.iterdir()) == []


def test_a_full_temporary_folder_is_one_line_and_leaves_no_world_files(tmp_path: Path) -> None:
    # The world's textures go to TMPDIR: full, the simulation cannot start.
    tmpdir = tmp_path / "tmp"
    tmpdir.mkdir()
    sweeps = tmp_path / "sweeps"
    done = _limited(
        4096,
        "sim",
        "--network",
        "tree:2",
        "--resolution",
        "32",
        "--save-sweeps",
        str(sweeps),
        tmpdir=tmpdir,
    )
    _one_error_line(done, "cannot write the world's texture files (File too large)")
    assert "libpng" not in done.stderr
    assert list(tmpdir.iterdir()) == []


def test_sweeps_that_do_not_fit_leave_no_half_written_folder(tmp_path: Path) -> None:
    # write_image_set in a process whose file size limit is below one image's size.
    script = (
        "import resource, sys, numpy as np\n"
        "from pipemap.errors import WriteError\n"
        "from pipemap.imagesets import write_image_set\n"
        "resource.setrlimit(resource.RLIMIT_FSIZE, (500, 500))\n"
        "import signal; signal.signal(signal.SIGXFSZ, signal.SIG_IGN)\n"
        "images = np.random.default_rng(0).integers(0, 255, (6, 64, 64, 3), dtype=np.uint8)\n"
        "try:\n"
        "    write_image_set(sys.argv[1], images, {'node': 'A'})\n"
        "except WriteError as exc:\n"
        "    print(exc)\n"
    )
    target = tmp_path / "sweep_001"
    done = subprocess.run(
        [sys.executable, "-c", script, str(target)], capture_output=True, text=True, timeout=120
    )
    assert done.stderr == ""
    assert done.stdout.strip() == f"{target}: cannot write (File too large)"
    assert list(tmp_path.iterdir()) == []


def test_a_killed_worlds_texture_folder_is_removed_by_the_next_world(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    ended = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True
    )
    dead_pid = int(ended.stdout)
    stale = tmp_path / f"pipemap-world-{dead_pid}-abcd1234"
    stale.mkdir()
    (stale / "pipe-A-B.png").write_bytes(b"texture")
    alive = tmp_path / f"pipemap-world-{os.getpid()}-efgh5678"
    alive.mkdir()
    folder = world._texture_folder()
    try:
        assert not stale.exists()
        assert alive.exists()  # a running process's folder stays
        assert Path(folder.name).name.startswith(f"pipemap-world-{os.getpid()}-")
    finally:
        folder.cleanup()
