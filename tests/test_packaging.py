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


@pytest.fixture(scope="module")
def plain_install(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A virtual environment holding the wheel as ``pip install .`` leaves it (no
    editable finder), with this environment's dependencies reachable through a path
    file; its ``bin`` folder."""
    venv = tmp_path_factory.mktemp("plain") / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    python = venv / "bin" / "python"
    subprocess.run(
        [str(python), "-m", "pip", "install", "--no-deps", "--quiet", str(wheel)],
        check=True,
        capture_output=True,
        timeout=300,
    )
    site = subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    # Plain directory entries only: this environment's own path files (among them the
    # editable install's finder) are not run there.
    deps = [p for p in sys.path if p.endswith("site-packages")]
    (Path(site) / "pipemap_test_deps.pth").write_text("\n".join(deps) + "\n")
    return venv / "bin"


def _from_checkout(bin_dir: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run(
        [str(bin_dir / "pipemap"), *args],
        cwd=ROOT,  # the checkout's own pipemap/ folder is right here
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_a_plain_install_records_from_the_checkout_folder(
    plain_install: Path, tmp_path: Path
) -> None:
    log = tmp_path / "run.mcap"
    done = _from_checkout(
        plain_install, "record", "--network", "paper", "--resolution", "32", "-o", str(log)
    )
    assert done.returncode in (0, 1), done.stderr  # 1: a tour that did not cover it all
    assert "No module named" not in done.stderr
    assert log.stat().st_size > 0
    info = _from_checkout(plain_install, "info", str(log))
    assert info.returncode == 0, info.stdout + info.stderr


def test_a_plain_install_batches_from_the_checkout_folder(
    plain_install: Path, tmp_path: Path
) -> None:
    spec = tmp_path / "one.toml"
    spec.write_text(
        'description = "one run"\n[grid]\nnetwork = ["paper"]\nseed = [0]\n'
        'condition = ["perfect"]\nresolution = [32]\nrule = ["default"]\n'
    )
    out = tmp_path / "out"
    done = _from_checkout(plain_install, "batch", str(spec), "--out", str(out), "--workers", "1")
    assert done.returncode == 0, done.stdout + done.stderr
    rows = (out / "results.csv").read_text().splitlines()
    assert len(rows) == 2 and ",ok," in rows[1], rows
