"""The layering the README's "Layout" section states, checked on the source with ``ast``.

Installed, everything lives under ``pipemap``; in the repository the layers keep
their top-level folders (``sim/``, ``recorder/``, ``replay/``, ``localizer/``), mapped
to ``pipemap.sim`` and so on by ``pyproject.toml``. The data travels one way,
``sim -> recorder -> log -> replay -> localizer -> map``; ``pipemap.errors`` sits
below every layer and imports nothing of pipemap; the batch machinery,
``pipemap.batch``, may import every layer and is imported by the command line alone;
only the command line, ``pipemap.cli``, may depend on everything. Every ``.py`` file
is parsed; every import it makes (at module level or inside a function, absolute or
relative, and ``importlib.import_module`` / ``__import__`` of a literal name) is checked
against the arrows allowed below. The localizer is held to more: only the standard library,
numpy, scipy, OpenCV and networkx, and nothing that touches files, the wall clock or
the logging set-up. Every module is at most 500 lines, but for any listed as being split.
Both rules come from the team's style guide (``../shared/STYLE.md``, beside the
checkout, not part of the repository); this docstring and the README restate them.
The checker's own tests are in ``test_architecture_checker.py``.
"""

from __future__ import annotations

import ast
import sys
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: Repository folder of each installed package (``[tool.setuptools.package-dir]``).
FOLDERS: dict[str, str] = {
    "pipemap": "pipemap",
    "pipemap.sim": "sim",
    "pipemap.recorder": "recorder",
    "pipemap.replay": "replay",
    "pipemap.localizer": "localizer",
}

#: Each area of the code, and the project modules it may import (a name and
#: everything below it). The most specific area of a module applies.
ALLOWED_INTERNAL: dict[str, tuple[str, ...]] = {
    "pipemap.errors": (),
    # The defaults of a run (camera, sweep, seed, lighting), written once for every layer.
    "pipemap.defaults": (),
    # glibc's allocator set up to keep freed memory (the CLI and batch workers call it).
    "pipemap.allocator": (),
    "pipemap": (),  # the root __init__: nothing of the project, so importing it is free
    "pipemap.localizer": ("pipemap.localizer", "pipemap.errors"),
    "pipemap.sim": ("pipemap.sim", "pipemap.errors", "pipemap.wholefile", "pipemap.defaults"),
    "pipemap.recorder": (
        "pipemap.recorder",
        "pipemap.pngcheck",
        "pipemap.wholefile",
        "pipemap.sim",
        "pipemap.localizer",
        "pipemap.errors",
        "pipemap.defaults",
    ),
    "pipemap.replay": (
        "pipemap.replay",
        "pipemap.recorder",
        "pipemap.localizer",
        "pipemap.errors",
        "pipemap.wholefile",
    ),
    # Image-set folders in the paper's layout: files in, localizer image sets out.
    "pipemap.imagesets": (
        "pipemap.localizer",
        "pipemap.errors",
        "pipemap.pngcheck",
        "pipemap.wholefile",
    ),
    # Byte-level checks of image formats, shared by the log and image-set readers.
    "pipemap.pngcheck": (),
    # Output files written under a temporary name and renamed when whole.
    "pipemap.wholefile": ("pipemap.errors",),
    # Stop signals raised as Ctrl-C is (the command line, a batch's driver).
    "pipemap.stops": ("pipemap.errors",),
    # The Python API: what the CLI calls, and what a script or notebook imports.
    "pipemap.api": (
        "pipemap.api",
        "pipemap.__version__",
        "pipemap.replay",
        "pipemap.recorder",
        "pipemap.sim",
        "pipemap.localizer",
        "pipemap.imagesets",
        "pipemap.sweep_folders",
        "pipemap.routes",
        "pipemap.interchange",
        "pipemap.viewing",
        "pipemap.errors",
    ),
    # A log and its replay in rerun (``pipemap view``), exported by the API.
    "pipemap.viewing": (
        "pipemap.api",
        "pipemap.replay",
        "pipemap.recorder",
        "pipemap.localizer",
        "pipemap.errors",
    ),
    # Other tools' formats in and out (ROS 2 bags, TUM, GeoJSON), exported by the API.
    "pipemap.interchange": (
        "pipemap.api",
        "pipemap.__version__",
        "pipemap.replay",
        "pipemap.recorder",
        "pipemap.localizer",
        "pipemap.errors",
    ),
    # Routes through a map document (``pipemap route``).
    "pipemap.routes": ("pipemap.localizer", "pipemap.errors"),
    # A simulated run's sweeps written as image-set folders (``pipemap sim``).
    "pipemap.sweep_folders": (
        "pipemap.imagesets",
        "pipemap.recorder",
        "pipemap.sim",
        "pipemap.errors",
    ),
    # Batch experiments: below the command line only, above every layer.
    "pipemap.batch": (
        "pipemap.batch",
        # Each run is recorded (and scored) as a script does it.
        "pipemap.api",
        "pipemap.recorder",
        "pipemap.replay",
        "pipemap.sim",
        "pipemap.localizer",
        "pipemap.errors",
        "pipemap.allocator",
        "pipemap.wholefile",
        "pipemap.stops",
        "pipemap.defaults",
        "pipemap.__version__",
    ),
    "pipemap.cli": ("pipemap",),
    "pipemap.__main__": ("pipemap.cli",),  # ``python -m pipemap``
}

#: Areas loaded by every layer: standard library only.
STDLIB_ONLY = (
    "pipemap.errors",
    "pipemap",
    "pipemap.pngcheck",
    "pipemap.allocator",
    "pipemap.defaults",
)

#: The names the layers had before they moved under ``pipemap``: importing one is
#: always wrong (installed, they do not exist).
OLD_TOP_LEVEL = ("sim", "recorder", "replay", "localizer")

#: Third-party packages the localizer may use besides the standard library.
LOCALIZER_THIRD_PARTY = ("numpy", "scipy", "cv2", "networkx")
#: Standard-library modules the localizer must not use: files, wall clock.
LOCALIZER_FORBIDDEN_STDLIB = ("os", "pathlib", "time", "datetime")
#: Calls that read or write files, by module: never in the localizer.
FILE_CALLS = {
    "cv2": {"imread", "imreadmulti", "imwrite", "imwritemulti", "VideoCapture", "VideoWriter"},
    "numpy": {
        "load",
        "save",
        "savez",
        "savez_compressed",
        "loadtxt",
        "savetxt",
        "genfromtxt",
        "fromfile",
        "memmap",
    },
    "io": {"open"},
    "builtins": {"open"},
    "codecs": {"open"},
}

#: Third-party packages the simulator must not know of: it knows nothing of MCAP
#: (the log format is the recorder's) nor of the viewer.
SIM_FORBIDDEN_THIRD_PARTY = ("mcap", "mcap_protobuf", "rerun")


@dataclass(frozen=True)
class Import:
    """One imported name: the dotted target and the line that imports it.

    ``from a.b import c`` gives ``a.b.c`` (``c`` may be a module or an attribute;
    either way the arrow points into ``a.b``); ``import a.b`` gives ``a.b``.
    """

    target: str
    lineno: int

    @property
    def top(self) -> str:
        """The top-level package or module imported."""
        return self.target.split(".")[0]


def module_of(relpath: str) -> str:
    """The installed dotted name of a repository file, e.g. ``sim/world.py`` ->
    ``pipemap.sim.world``; a package's ``__init__.py`` gives the package."""
    parts = relpath.removesuffix(".py").split("/")
    if parts[-1] == "__init__":
        parts = parts[:-1]
    for package, folder in sorted(FOLDERS.items(), key=lambda kv: -len(kv[1])):
        if parts[0] == folder:
            return ".".join([package, *parts[1:]])
    raise ValueError(f"{relpath} is in no package folder")


def _package_of(relpath: str) -> list[str]:
    """The dotted package a file's relative imports start from, as parts."""
    module = module_of(relpath).split(".")
    # "." is the file's own package: the module itself for an __init__.py.
    return module if relpath.endswith("__init__.py") else module[:-1]


def imports_of(tree: ast.AST, relpath: str) -> list[Import]:
    """Every import in ``tree`` (anywhere in it), relative ones made absolute."""
    package = _package_of(relpath)
    found: list[Import] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [Import(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                base = node.module or ""
            else:
                up = node.level - 1
                if up >= len(package):
                    # Above the top-level package: no layer may reach out that way.
                    base = "<beyond top level>"
                else:
                    parts = package[: len(package) - up]
                    base = ".".join(parts + [node.module] if node.module else parts)
            found += [
                Import(base if alias.name == "*" else f"{base}.{alias.name}", node.lineno)
                for alias in node.names
            ]
        elif isinstance(node, ast.Call) and node.args:
            first = node.args[0]
            func = node.func
            dynamic = (isinstance(func, ast.Name) and func.id == "__import__") or (
                isinstance(func, ast.Attribute) and func.attr == "import_module"
            )
            if dynamic and isinstance(first, ast.Constant) and isinstance(first.value, str):
                found.append(Import(first.value, node.lineno))
    return found


def _within(target: str, allowed: tuple[str, ...]) -> bool:
    return any(target == a or target.startswith(a + ".") for a in allowed)


def _module_aliases(tree: ast.AST) -> dict[str, str]:
    """Local names bound to a module by ``import x`` / ``import x as y``."""
    aliases: dict[str, str] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.asname:
                    aliases[alias.asname] = alias.name
                else:
                    top = alias.name.split(".")[0]
                    aliases[top] = top
    return aliases


def _localizer_calls(tree: ast.AST, relpath: str) -> list[str]:
    """File, clock and logging set-up calls that the pure core must not make."""
    aliases = _module_aliases(tree)
    problems = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            if isinstance(func, ast.Name) and func.id == "open":
                problems.append(f"{relpath}:{node.lineno}: calls the builtin open()")
            elif isinstance(func, ast.Attribute) and isinstance(func.value, ast.Name):
                module = aliases.get(func.value.id, "")
                if func.attr in FILE_CALLS.get(module, ()):
                    problems.append(
                        f"{relpath}:{node.lineno}: calls {module}.{func.attr}() (file access)"
                    )
        if isinstance(node, ast.Attribute) and node.attr == "basicConfig":
            problems.append(f"{relpath}:{node.lineno}: uses logging.basicConfig (logging set-up)")
    return problems


def area_of(module: str) -> str:
    """The most specific key of :data:`ALLOWED_INTERNAL` that holds ``module``."""
    matches = [area for area in ALLOWED_INTERNAL if _within(module, (area,))]
    return max(matches, key=len)


def violations(source: str, relpath: str) -> list[str]:
    """Every arrow in ``source`` (the file ``relpath``, e.g. ``"sim/world.py"``) that
    runs the wrong way, each as ``"file:line: message"``; ``[]`` if there is none."""
    tree = ast.parse(source, filename=relpath)
    area = area_of(module_of(relpath))
    allowed = ALLOWED_INTERNAL[area]
    problems: list[str] = []
    for imp in imports_of(tree, relpath):
        where = f"{relpath}:{imp.lineno}: imports {imp.target!r}"
        if imp.target.startswith("<"):
            problems.append(f"{where}: a relative import above the top-level package")
        elif imp.top in OLD_TOP_LEVEL:
            problems.append(f"{where}: the layers live under pipemap (pipemap.{imp.target})")
        elif area in STDLIB_ONLY and imp.top not in sys.stdlib_module_names:
            problems.append(f"{where}: {area} is loaded by every layer; stdlib only")
        elif imp.top == "pipemap" and not _within(imp.target, allowed):
            names = ", ".join(allowed) or "nothing"
            problems.append(f"{where}: {area} may import only {names} of the project")
        elif area == "pipemap.localizer":
            if imp.top in LOCALIZER_FORBIDDEN_STDLIB:
                problems.append(f"{where}: the localizer touches no files and no clock")
            elif imp.target == "logging.basicConfig":
                problems.append(f"{where}: only the CLI configures logging")
            elif not (
                imp.top == "pipemap"
                or imp.top in sys.stdlib_module_names
                or imp.top in LOCALIZER_THIRD_PARTY
            ):
                names = ", ".join(LOCALIZER_THIRD_PARTY)
                problems.append(f"{where}: the localizer may use only the stdlib and {names}")
        elif area == "pipemap.sim" and imp.top in SIM_FORBIDDEN_THIRD_PARTY:
            problems.append(f"{where}: the simulator knows nothing of logs or viewers")
    if area == "pipemap.localizer":
        problems += _localizer_calls(tree, relpath)
    return problems


def source_files() -> list[str]:
    """Every ``.py`` file of the packages, relative to the repository root."""
    files = []
    for folder in FOLDERS.values():
        for path in sorted((ROOT / folder).rglob("*.py")):
            if "__pycache__" not in path.parts:
                files.append(path.relative_to(ROOT).as_posix())
    return sorted(set(files))


# ---------------------------------------------------------------- the project itself


def test_the_package_map_is_the_build_backends() -> None:
    """The folders checked here are the ones pyproject.toml installs."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert config["package-dir"] == {k: v for k, v in FOLDERS.items() if k != "pipemap"}
    for package in config["packages"]:
        assert package.split(".")[0] == "pipemap", f"{package} installs outside pipemap"


def test_every_package_is_walked() -> None:
    files = source_files()
    for folder in FOLDERS.values():
        assert f"{folder}/__init__.py" in files, f"{folder} not found under {ROOT}"
    # The walk reaches the modules that make the arrows, not only the __init__ files.
    assert "localizer/fastmatch.py" in files
    assert "pipemap/cli/app.py" in files


def test_the_walker_sees_real_imports() -> None:
    """Guards against a checker that passes because it collects nothing."""
    path = "pipemap/cli/folder_commands.py"
    targets = {imp.target for imp in imports_of(ast.parse((ROOT / path).read_text()), path)}
    assert "pipemap.localizer.LocalizerConfig" in targets
    assert "pipemap.api" in targets


@pytest.mark.parametrize("relpath", source_files())
def test_imports_follow_the_layering(relpath: str) -> None:
    source = (ROOT / relpath).read_text(encoding="utf-8")
    problems = violations(source, relpath)
    assert not problems, "imports that run the wrong way:\n" + "\n".join(problems)


# ---------------------------------------------------------------- module size

#: A module is one idea, most of them 50 to 500 lines (the style guide). The upper
#: bound holds for every module of the packages.
MAX_MODULE_LINES = 500

#: Modules still over the bound, each being split by a change under way (none since
#: issue 21 split the last ones). Take a file out when its split lands: a test fails
#: while a listed file fits, so the list always shows what is left.
OVERSIZED_FOR_NOW: frozenset[str] = frozenset()


def module_lines(path: Path) -> int:
    """How many lines the file at ``path`` has."""
    return len(path.read_text(encoding="utf-8").splitlines())


def oversized(root: Path, relpaths: list[str], allowed: frozenset[str] = frozenset()) -> list[str]:
    """Each of ``relpaths`` (below ``root``) longer than :data:`MAX_MODULE_LINES` and
    not in ``allowed``, as ``"file: N lines"``."""
    lengths = {relpath: module_lines(root / relpath) for relpath in relpaths}
    return [
        f"{relpath}: {n} lines"
        for relpath, n in lengths.items()
        if n > MAX_MODULE_LINES and relpath not in allowed
    ]


def test_modules_are_at_most_500_lines() -> None:
    problems = oversized(ROOT, source_files(), OVERSIZED_FOR_NOW)
    assert not problems, (
        f"modules over {MAX_MODULE_LINES} lines (split them by idea):\n" + "\n".join(problems)
    )


def test_the_list_of_oversized_modules_shows_what_is_left() -> None:
    files = source_files()
    for relpath in sorted(OVERSIZED_FOR_NOW):
        assert relpath in files, f"{relpath} is gone: take it out of OVERSIZED_FOR_NOW"
        n = module_lines(ROOT / relpath)
        assert n > MAX_MODULE_LINES, f"{relpath} is {n} lines now: take it out of OVERSIZED_FOR_NOW"


def test_the_size_check_catches_a_long_module(tmp_path: Path) -> None:
    (tmp_path / "sim").mkdir()
    (tmp_path / "sim" / "long.py").write_text("x = 1\n" * (MAX_MODULE_LINES + 1))
    (tmp_path / "sim" / "fits.py").write_text("x = 1\n" * MAX_MODULE_LINES)
    files = ["sim/long.py", "sim/fits.py"]
    assert oversized(tmp_path, files) == [f"sim/long.py: {MAX_MODULE_LINES + 1} lines"]
    assert oversized(tmp_path, files, frozenset({"sim/long.py"})) == []
