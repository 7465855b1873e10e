"""What ``pip install pipemap`` puts on a machine: one top-level name, nothing else.

The repository keeps the layers in top-level folders (``sim/``, ``localizer/``, ...);
the build backend maps them under ``pipemap``. These tests build the real wheel and
import from it, outside the repository, so that a folder name leaking into
site-packages (or a module left out of the map) fails here and not on a user's
machine. The suite itself runs on an editable install, which checks that those work.
"""

from __future__ import annotations

import os
import re
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


def _venv_with(wheel: Path, venv: Path, deps: list[str]) -> Path:
    """A new virtual environment at ``venv`` holding the wheel (no dependencies
    installed) and a path file naming the folders ``deps``; its ``bin`` folder."""
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
    (Path(site) / "pipemap_test_deps.pth").write_text("\n".join(deps) + "\n")
    return venv / "bin"


@pytest.fixture(scope="module")
def plain_install(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A virtual environment holding the wheel as ``pip install .`` leaves it (no
    editable finder), with this environment's dependencies reachable through a path
    file; its ``bin`` folder."""
    # Plain directory entries only: this environment's own path files (among them the
    # editable install's finder) are not run there.
    deps = [p for p in sys.path if p.endswith("site-packages")]
    return _venv_with(wheel, tmp_path_factory.mktemp("plain") / "venv", deps)


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
    # tree:2 (S, n1: 3 sweeps): the writer process starts as for any network.
    log = tmp_path / "run.mcap"
    done = _from_checkout(
        plain_install, "record", "--network", "tree:2", "--resolution", "32", "-o", str(log)
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
        'description = "one run"\n[grid]\nnetwork = ["tree:2"]\nseed = [0]\n'
        'condition = ["perfect"]\nresolution = [32]\nrule = ["default"]\n'
    )
    out = tmp_path / "out"
    done = _from_checkout(plain_install, "batch", str(spec), "--out", str(out), "--workers", "1")
    assert done.returncode == 0, done.stdout + done.stderr
    rows = (out / "results.csv").read_text().splitlines()
    assert len(rows) == 2 and ",ok," in rows[1], rows


def test_the_wheel_ships_py_typed_and_the_license(wheel: Path) -> None:
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        metadata = archive.read(next(n for n in names if n.endswith(".dist-info/METADATA")))
    assert "pipemap/py.typed" in names  # a user's mypy checks calls into pipemap
    (license_file,) = [n for n in names if n.endswith("/LICENSE")]
    assert ".dist-info/" in license_file
    with zipfile.ZipFile(wheel) as archive:
        assert b"MIT License" in archive.read(license_file)
    from pipemap import __version__

    assert f"\nVersion: {__version__}\n".encode() in metadata


#: The packages of the extras, which the core install must do without.
EXTRA_MODULES = ("pybullet", "ray", "rerun")


def _requirements(names: list[str]) -> list[str]:
    """The distribution names of Requires-Dist lines, those of extras left out."""
    wanted = []
    for line in names:
        if "extra ==" in line:
            continue
        match = re.match(r"[A-Za-z0-9._-]+", line)
        if match:
            wanted.append(match.group(0))
    return wanted


def _core_closure(wheel: Path) -> set[str]:
    """The distributions the wheel's core needs, found in this environment: its own
    Requires-Dist without extras, and theirs, over and over."""
    from importlib import metadata

    with zipfile.ZipFile(wheel) as archive:
        text = archive.read(
            next(n for n in archive.namelist() if n.endswith(".dist-info/METADATA"))
        ).decode()
    todo = _requirements(
        [line[15:] for line in text.splitlines() if line.startswith("Requires-Dist: ")]
    )
    seen: set[str] = set()
    while todo:
        name = todo.pop()
        key = re.sub(r"[-_.]+", "-", name).lower()
        if key in seen:
            continue
        try:
            dist = metadata.distribution(name)
        except metadata.PackageNotFoundError:
            continue  # a dependency under a marker that does not hold here
        seen.add(key)
        todo.extend(_requirements(dist.requires or []))
    return seen


@pytest.fixture(scope="module")
def core_install(wheel: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A virtual environment holding the wheel and its core dependencies alone: this
    environment's copies of them, linked into a folder of their own that a path file
    names (nothing of the extras is there); its ``bin`` folder."""
    from importlib import metadata

    base = tmp_path_factory.mktemp("core")
    core_site = base / "deps"
    core_site.mkdir()
    for name in _core_closure(wheel):
        dist = metadata.distribution(name)
        root = Path(str(dist.locate_file("")))
        tops = {Path(str(f)).parts[0] for f in dist.files or [] if not str(f).startswith("..")}
        for top in tops:
            if not (core_site / top).exists() and (root / top).exists():
                (core_site / top).symlink_to(root / top)
    return _venv_with(wheel, base / "venv", [str(core_site)])


def _core(bin_dir: Path, cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run(
        [str(bin_dir / "pipemap"), *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )


def test_the_core_install_has_none_of_the_extras(core_install: Path, tmp_path: Path) -> None:
    for module in EXTRA_MODULES:
        done = subprocess.run(
            [str(core_install / "python"), "-c", f"import {module}"],
            cwd=tmp_path,
            capture_output=True,
        )
        assert done.returncode != 0, f"{module} is importable: the test would prove nothing"


def test_the_core_install_replays_and_scores_a_stored_log(
    core_install: Path, tmp_path: Path
) -> None:
    import json

    log = ROOT / "recordings" / "paper_autonomous.mcap"
    scored = _core(core_install, tmp_path, "score", str(log), "--json")
    assert scored.returncode == 0, scored.stderr
    expected = json.loads((ROOT / "recordings" / "paper_autonomous.score.json").read_text())
    report = json.loads(scored.stdout)
    assert report["map_correct"] is True and report["decisions"] == expected["decisions"]
    replayed = _core(core_install, tmp_path, "replay", str(log), "-o", str(tmp_path / "m.json"))
    assert replayed.returncode == 0, replayed.stderr
    assert (tmp_path / "m.json").read_bytes() == (
        ROOT / "recordings" / "paper_autonomous.map.json"
    ).read_bytes()
    info = _core(core_install, tmp_path, "info", str(log))
    assert info.returncode == 0, info.stderr


@pytest.mark.parametrize(
    ("args", "extra"),
    [
        (["record", "--network", "paper", "-o", "run.mcap"], "sim"),
        (["sim", "--network", "paper", "--save-sweeps", "sweeps"], "sim"),
        (["batch", "spec.toml", "--out", "out"], "sim"),
        (["view", "{log}", "--save", "run.rrd"], "view"),
    ],
    ids=["record", "sim", "batch", "view"],
)
def test_a_command_whose_extra_is_missing_names_it(
    core_install: Path, tmp_path: Path, args: list[str], extra: str
) -> None:
    log = str(ROOT / "recordings" / "paper_autonomous.mcap")
    done = _core(core_install, tmp_path, *(a.format(log=log) for a in args))
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1, done.stderr
    assert f'pip install "pipemap[{extra}]"' in done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # nothing written
