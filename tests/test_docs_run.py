"""The manual runs as written: every ``sh`` block of README.md and docs/*.md is run.

A command in the manual is a test, so a page cannot drift from the code. Each page's
blocks run in order, in one temporary folder (so a later block may read the log an
earlier one recorded), under ``bash -e -o pipefail``: every command must exit 0. The
blocks of a page in ``BLOCKS_APART`` read nothing of each other's: each runs alone, in
a folder of its own, so that a parallel run spreads them over its workers. The
folder links the checkout's ``recordings/``, ``experiments/``, ``benchmarks/`` and
``docs/``, and the team's ``shared/`` folder sits beside it as ``../shared`` does beside
the checkout; ``pipemap`` and ``python`` are this interpreter's.

HTML comments on the lines just above a block's fence steer it:

- ``<!-- doc-test: substitute OLD => NEW -->`` runs the block with OLD replaced by NEW
  (small settings: fewer pixels, a smaller network). OLD must occur in the block.
- ``<!-- doc-test: skip (REASON) -->`` does not run it; the test of that block is
  reported skipped with the reason. For blocks that install pipemap (CI runs the Quick
  start in fresh virtual environments), want several machines, a display, or stop
  processes that are not theirs.
- ``<!-- doc-test: covered -->`` does not run the block on its own, because another
  block of the page that runs runs each of its commands: every command of the block
  (its substitutions made, compared word for word as the shell splits them, comments
  aside) is a command of such a block, or is one but for a ``--keep DIR`` that the
  other adds (the benchmarks' option to keep their logs). A page whose runs repeat
  at doc-test settings runs each once. The page is an error if a command of a
  covered block has no such twin; the block's own test checks its twins run.

Blocks that are not commands (a synopsis, an output) are fenced ``text``, not ``sh``.
"""

from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINKED = ("recordings", "experiments", "benchmarks", "docs")
#: Longest one block may take on the busy 2-core machine, with its small settings; a
#: block that hangs fails here rather than holding the suite.
BLOCK_TIMEOUT_S = 600

FENCE = re.compile(r"^```(\w*)[^\n]*\n(.*?)^```", re.S | re.M)
MARKER = re.compile(r"^<!--\s*doc-test:\s*(.*?)\s*-->$")


@dataclass(frozen=True)
class Block:
    """One ``sh`` block: where it is, its commands as they run, and why not, if not."""

    page: Path
    line: int
    script: str
    skip: str | None
    covered: bool = False

    @property
    def runs(self) -> bool:
        """Whether the block runs as a unit's part (not skipped, not covered)."""
        return self.skip is None and not self.covered

    @property
    def name(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def _markers(text: str, fence_start: int) -> list[str]:
    """The doc-test comments on the lines right above a fence, top to bottom."""
    found: list[str] = []
    for line in reversed(text[:fence_start].splitlines()):
        match = MARKER.match(line.strip())
        if not match:
            break
        found.append(match.group(1))
    return found[::-1]


def _substitution(marker: str, where: str) -> tuple[str, str]:
    body = marker.removeprefix("substitute").strip()
    old, sep, new = body.partition("=>")
    if not sep or not old.strip():
        raise ValueError(f"{where}: a substitution reads 'substitute OLD => NEW': {marker!r}")
    return old.strip(), new.strip()


def commands(script: str) -> list[tuple[str, ...]]:
    """A script's commands, one a line, each as the words the shell splits it into
    (comments and blank lines dropped, a line ending in a backslash joined to the
    next; a line whose quotes close on another, as its text alone)."""
    found = []
    for line in script.replace("\\\n", " ").splitlines():
        try:
            words = tuple(shlex.split(line, comments=True))
        except ValueError:
            words = (line.strip(),)
        if words:
            found.append(words)
    return found


def _less_keep(words: tuple[str, ...]) -> tuple[str, ...]:
    """A command without its ``--keep DIR`` (itself, if it has none)."""
    if "--keep" not in words[:-1]:
        return words
    at = words.index("--keep")
    return words[:at] + words[at + 2 :]


def twins(block: Block, blocks: list[Block]) -> list[Block]:
    """The blocks among ``blocks`` that run the commands of ``block``, one for each of
    its commands, in order. ``ValueError`` names a command that no block runs."""
    found = []
    for command in commands(block.script):
        twin = next(
            (
                other
                for other in blocks
                if other is not block
                and other.runs
                and any(
                    command in (theirs, _less_keep(theirs)) for theirs in commands(other.script)
                )
            ),
            None,
        )
        if twin is None:
            raise ValueError(
                f"{block.page.name}:{block.line}: covered, but no block of the page that runs has "
                f"the command {shlex.join(command)!r}"
            )
        found.append(twin)
    return found


def parse_blocks(page: Path, text: str) -> list[Block]:
    """Every ``sh`` block of a page, its markers applied. A marker that is neither a
    skip, a substitution nor ``covered``, a substitution whose OLD is not in the block,
    or a covered block with a command no other block runs, is an error: the page and
    its markers must not drift apart either."""
    blocks: list[Block] = []
    for fence in FENCE.finditer(text):
        if fence.group(1) != "sh":
            continue
        line = text.count("\n", 0, fence.start()) + 1
        where = f"{page.name}:{line}"
        script, skip, covered = fence.group(2), None, False
        for marker in _markers(text, fence.start()):
            if marker.startswith("skip"):
                reason = re.fullmatch(r"skip\s*\((.+)\)", marker)
                if not reason:
                    raise ValueError(f"{where}: a skip names its reason: skip (REASON)")
                skip = reason.group(1)
            elif marker.startswith("substitute"):
                old, new = _substitution(marker, where)
                if old not in script:
                    raise ValueError(f"{where}: {old!r} is not in the block to substitute")
                script = script.replace(old, new)
            elif marker == "covered":
                covered = True
            else:
                raise ValueError(f"{where}: unknown doc-test marker {marker!r}")
        blocks.append(Block(page, line, script, skip, covered))
    for block in blocks:
        if block.covered:
            twins(block, blocks)
    return blocks


def _all_blocks() -> list[Block]:
    return [b for page in PAGES for b in parse_blocks(page, page.read_text())]


def _workspace(tmp_path: Path) -> Path:
    """A folder with the checkout's data linked in and ``../shared`` beside it."""
    work = tmp_path / "work"
    work.mkdir()
    for name in LINKED:
        (work / name).symlink_to(ROOT / name)
    shared = ROOT.parent / "shared"
    if shared.is_dir():
        (tmp_path / "shared").symlink_to(shared)
    return work


def _run_page(blocks: list[Block], tmp_path: Path) -> int:
    """Run ``blocks`` in order in one folder; fail at the first that exits non-zero or
    times out. Returns how many ran to the end (all of them when it returns)."""
    work = _workspace(tmp_path)
    bindir = str(Path(sys.executable).parent)
    env = {**os.environ, "PATH": bindir + os.pathsep + os.environ.get("PATH", "")}
    env.pop("PYTHONPATH", None)  # the installed pipemap, as a user runs it
    ran = 0
    for block in blocks:
        # A session of its own, so that a block that times out is stopped whole: the
        # commands bash started (a simulator run, a benchmark) go with it, not on as
        # orphans that load the machine after the test has failed.
        with subprocess.Popen(
            ["bash", "-e", "-o", "pipefail", "-c", block.script],
            cwd=work,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        ) as proc:
            try:
                stdout, stderr = proc.communicate(timeout=BLOCK_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.communicate()
                pytest.fail(f"{block.name} did not finish in {BLOCK_TIMEOUT_S} s:\n{block.script}")
        done = subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)
        if done.returncode != 0:
            pytest.fail(
                f"{block.name} exited {done.returncode}:\n{block.script}\n"
                f"--- stdout (end)\n{done.stdout[-2000:]}\n--- stderr (end)\n{done.stderr[-2000:]}"
            )
        ran += 1
    return ran


_BLOCKS = _all_blocks()
_RUN_PAGES = sorted({b.page for b in _BLOCKS if b.runs})


#: Pages whose blocks read nothing an earlier block wrote: each block runs in a folder
#: of its own, as a unit of work of its own (below). Their blocks are long (recordings,
#: benchmarks); apart, they spread over the workers of a parallel run.
BLOCKS_APART = frozenset(
    {"docs/lighting.md", "docs/lookalike.md", "docs/recorder.md", "docs/simulator.md"}
)


def _units() -> list[tuple[str, list[Block]]]:
    """What runs together, in one folder: a page's blocks, or one block of a page of
    :data:`BLOCKS_APART`; each with a name for its class (the page, and the block's
    place among the page's blocks that run, from 1)."""
    units = []
    for page in _RUN_PAGES:
        blocks = [b for b in _BLOCKS if b.page == page and b.runs]
        stem = re.sub(r"\W", "_", page.relative_to(ROOT).with_suffix("").as_posix())
        if page.relative_to(ROOT).as_posix() in BLOCKS_APART:
            units += [(f"TestPage_{stem}_{i}", [b]) for i, b in enumerate(blocks, 1)]
        else:
            units.append((f"TestPage_{stem}", blocks))
    return units


def _unit_class(name: str, blocks: list[Block]) -> type:
    """A class whose one test runs ``blocks``. A class, not a parameter: run with
    ``pytest -n N --dist loadscope``, each class is a unit of work of its own, so the
    pages spread over the workers (a module's functions would all go to one)."""

    def test_the_sh_blocks_run(self: object, tmp_path: Path) -> None:
        assert _run_page(blocks, tmp_path) == len(blocks)

    body = {"test_the_sh_blocks_run": test_the_sh_blocks_run, "__module__": __name__}
    return type(name, (), body)


for _name, _blocks in _units():
    globals()[_name] = _unit_class(_name, _blocks)


@pytest.mark.parametrize("block", [b for b in _BLOCKS if b.skip is not None], ids=lambda b: b.name)
def test_a_skipped_block_says_why(block: Block) -> None:
    assert block.skip is not None and block.skip.strip(), f"{block.name}: skipped without a reason"
    pytest.skip(block.skip)


@pytest.mark.parametrize("block", [b for b in _BLOCKS if b.covered], ids=lambda b: b.name)
def test_a_covered_block_runs_in_its_twins(block: Block) -> None:
    """Each command of a covered block is a command of a block that one of the
    units above runs."""
    page = [b for b in _BLOCKS if b.page == block.page]
    running = [b for _, unit in _units() for b in unit]
    found = twins(block, page)
    assert len(found) == len(commands(block.script)) > 0
    assert all(any(twin is b for b in running) for twin in found)


# ------------------------------------------------------------- the runner itself


def test_markers_substitute_and_skip() -> None:
    text = (
        "intro\n\n<!-- doc-test: substitute --resolution 400 => --resolution 32 -->\n"
        "```sh\npipemap record --resolution 400\n```\n\n"
        "<!-- doc-test: skip (needs a cluster) -->\n```sh\nray start\n```\n"
        "```text\npipemap synopsis [--flag]\n```\n"
    )
    first, second = parse_blocks(Path("page.md"), text)
    assert first.script == "pipemap record --resolution 32\n" and first.skip is None
    assert first.line == 4
    assert second.skip == "needs a cluster" and second.script == "ray start\n"


def test_a_covered_block_names_its_twins_and_does_not_run() -> None:
    text = (
        "<!-- doc-test: substitute --count 8 => --count 1 -->\n<!-- doc-test: covered -->\n"
        "```sh\nbench --count 8   # all eight\nbench --count 8 \\\n  --no-probes\n```\n"
        "```sh\nbench --count 1 --keep on\n```\n"
        "```sh\nbench --count 1 --no-probes\nscore\n```\n"
    )
    covered, first, second = parse_blocks(Path("page.md"), text)
    assert covered.covered and not covered.runs and first.runs and second.runs
    assert commands(covered.script) == [
        ("bench", "--count", "1"),
        ("bench", "--count", "1", "--no-probes"),
    ]
    assert commands("echo 'two\nlines'\n") == [("echo 'two",), ("lines'",)]
    assert twins(covered, [covered, first, second]) == [first, second]
    assert _RUN_PAGES and all(b.runs for _, unit in _units() for b in unit)


@pytest.mark.parametrize(
    "others",
    [
        "```sh\nbench --count 1 --fast\n```\n",  # another command
        "```sh\nbench --count 1 --out on\n```\n",  # only --keep may differ
        "<!-- doc-test: skip (x) -->\n```sh\nbench --count 1\n```\n",  # does not run
        "<!-- doc-test: covered -->\n```sh\nbench --count 1\n```\n",  # nor does this
        "```text\nbench --count 1\n```\n",  # not a command
    ],
)
def test_a_covered_block_without_a_running_twin_is_an_error(others: str) -> None:
    text = "<!-- doc-test: covered -->\n```sh\nbench --count 1\n```\n" + others
    with pytest.raises(ValueError, match="covered"):
        parse_blocks(Path("page.md"), text)


def test_a_marker_apart_from_its_block_does_not_steer_it() -> None:
    text = "<!-- doc-test: skip (x) -->\n\nprose\n```sh\ntrue\n```\n"
    (block,) = parse_blocks(Path("page.md"), text)
    assert block.skip is None


@pytest.mark.parametrize(
    "marker",
    [
        "substitute --px 9 => --px 1",  # not in the block
        "substitute --px 400",  # no =>
        "skip",  # no reason
        "run twice",  # unknown
    ],
)
def test_a_bad_marker_is_an_error(marker: str) -> None:
    text = f"<!-- doc-test: {marker} -->\n```sh\npipemap record --px 400\n```\n"
    with pytest.raises(ValueError):
        parse_blocks(Path("page.md"), text)


def test_a_failing_command_fails_the_page(tmp_path: Path) -> None:
    """bash -e: a failing command in the middle of a block fails it, not only the last."""
    block = Block(ROOT / "README.md", 1, "false\ntrue\n", None)
    with pytest.raises(pytest.fail.Exception, match="exited 1"):
        _run_page([block], tmp_path)


def test_a_block_that_times_out_is_stopped_with_what_it_started(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A timed-out block's commands are stopped too, not left running as orphans."""
    monkeypatch.setattr(sys.modules[__name__], "BLOCK_TIMEOUT_S", 2)
    pid_file = tmp_path / "child.pid"
    block = Block(ROOT / "README.md", 1, f"sleep 60 &\necho $! > {pid_file}\nwait\n", None)
    with pytest.raises(pytest.fail.Exception, match="did not finish in 2 s"):
        _run_page([block], tmp_path)
    child = int(pid_file.read_text())
    try:
        os.kill(child, 0)
    except ProcessLookupError:
        return  # gone, as it should be
    # A zombie not yet reaped by init is stopped too: it holds no state but Z.
    state = Path(f"/proc/{child}/stat").read_text().split()[2]
    assert state == "Z", f"the block's sleep {child} is still running ({state})"


def test_a_block_sees_the_checkout_and_shared(tmp_path: Path) -> None:
    script = "test -d recordings && test -f experiments/small.toml && command -v pipemap\n"
    if (ROOT.parent / "shared").is_dir():
        script += "test -d ../shared\n"
    assert _run_page([Block(ROOT / "README.md", 1, script, None)], tmp_path) == 1


def test_every_install_block_is_skipped() -> None:
    """CI runs the installs (the Quick start, in fresh virtual environments); run here
    they would reinstall the package under test."""
    installs = [b.name for b in _BLOCKS if "pip install" in b.script and b.skip is None]
    assert not installs, f"blocks that install but are not skipped: {installs}"


def test_every_page_apart_is_a_page_that_runs() -> None:
    pages = {p.relative_to(ROOT).as_posix() for p in _RUN_PAGES}
    assert pages >= BLOCKS_APART, f"not pages with blocks that run: {BLOCKS_APART - pages}"
