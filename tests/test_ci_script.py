""".ci/run on a stand-in README: it runs both Quick start lines, keeps their exit status,
and leaves no virtual environment behind.

Each real run makes two fresh environments (about 2.7 GiB together); a CI machine that
keeps them fills its disk after a few runs and then fails on install ("No space left on
device"), whatever the code. The stand-in's two lines are shell built-ins, so this test
creates the two environments but installs nothing into them.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _checkout_with_quick_start(tmp_path: Path, first: str, second: str) -> Path:
    checkout = tmp_path / "checkout"
    (checkout / ".ci").mkdir(parents=True)
    shutil.copy2(ROOT / ".ci" / "run", checkout / ".ci" / "run")
    (checkout / "README.md").write_text(
        f"# stand-in\n\n## Quick start\n\n```sh\n{first}\n{second}\n```\n", encoding="utf-8"
    )
    return checkout


def _run_ci(checkout: Path, tmpdir: Path) -> subprocess.CompletedProcess[str]:
    tmpdir.mkdir()
    env = {**os.environ, "TMPDIR": str(tmpdir)}
    return subprocess.run(
        ["bash", str(checkout / ".ci" / "run")],
        capture_output=True,
        text=True,
        env=env,
        timeout=600,
        check=False,
    )


def test_ci_runs_both_lines_keeps_the_failure_and_removes_its_environments(tmp_path: Path) -> None:
    checkout = _checkout_with_quick_start(tmp_path, "echo first-line-ran", "exit 7")
    tmpdir = tmp_path / "t"
    done = _run_ci(checkout, tmpdir)
    assert "first-line-ran" in done.stdout
    assert done.returncode == 7  # the second line ran, and its status is CI's
    assert list(tmpdir.iterdir()) == []
