"""What ``pip install pipemap`` puts on a machine: one top-level name, nothing else.

The repository keeps the layers in top-level folders (``sim/``, ``localizer/``, ...);
the build backend maps them under ``pipemap``. These tests build the real wheel and
import from it, outside the repository, so that a folder name leaking into
site-packages (or a module left out of the map) fails here and not on a user's
machine. The suite itself runs on an editable install, which checks that those work.
"""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The wheel of this checkout, built as pip builds it for ``pip install .``."""
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(out), str(ROOT)],
        check=True,
        capture_output=True,
        timeout=600,
    )
    (built,) = out.glob("pipemap-*.whl")
    return built


def test_the_wheel_installs_one_top_level_name(wheel: Path) -> None:
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        top_level = archive.read(
            next(n for n in names if n.endswith(".dist-info/top_level.txt"))
        ).decode()
    tops = {name.split("/")[0] for name in names if not name.split("/")[0].endswith(".dist-info")}
    assert tops == {"pipemap"}
    assert top_level.split() == ["pipemap"]
    for module in (
        "sim/world.py",
        "localizer/fastmatch.py",
        "replay/score.py",
        "cli/app.py",
        "batch/engine.py",
    ):
        assert f"pipemap/{module}" in names
    assert "pipemap/recorder/schemas/pipemap_log.proto" in names


def test_installed_layers_import_under_pipemap_only(wheel: Path, tmp_path: Path) -> None:
    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "--quiet", "-t", str(target), wheel],
        check=True,
        capture_output=True,
        timeout=300,
    )
    env = {**os.environ, "PYTHONPATH": str(target)}
    probe = (
        "import pipemap.sim, pipemap.localizer, pipemap.replay, pipemap.recorder, pipemap.cli\n"
        "import pipemap.batch\n"
        "for m in (pipemap.sim, pipemap.localizer, pipemap.replay, pipemap.cli, pipemap.batch):\n"
        "    print(m.__file__)\n"
    )
    # Run outside the repository, so that its folders cannot be found through the cwd.
    done = subprocess.run(
        [sys.executable, "-c", probe], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    for line in done.stdout.split():
        assert Path(line).is_relative_to(target), line
    for old in ("sim", "localizer", "replay", "recorder"):
        gone = subprocess.run(
            [sys.executable, "-c", f"import {old}"], cwd=tmp_path, env=env, capture_output=True
        )
        assert gone.returncode != 0, f"'import {old}' works: a layer leaked out of pipemap"
