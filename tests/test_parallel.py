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
from tests.schedule import SlowestFirst

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


# ------------------------------------------------- the order of the work (tests/schedule.py)


class _Node:
    """A worker as the scheduler sees it: it is sent indices of tests to run."""

    def __init__(self, name: str) -> None:
        self.gateway = type("Gateway", (), {"id": name})()
        self.sent: list[int] = []
        self.shutting_down = False

    def send_runtest_some(self, indices: list[int]) -> None:
        self.sent.extend(indices)

    def shutdown(self) -> None:
        self.shutting_down = True


class _Config:
    option = type("Option", (), {"loadscopereorder": True})()

    def getvalue(self, name: str) -> object:
        return {"tx": ["2*popen"], "dist": "loadscope"}[name]


def _scheduled(
    collection: list[str], seconds: dict[str, float], exclusive: frozenset[str] = frozenset()
) -> tuple[SlowestFirst, list[_Node]]:
    """A scheduler for two workers, its collection handed out."""
    import tests.schedule

    old = dict(tests.schedule.SECONDS)
    tests.schedule.SECONDS.clear()
    tests.schedule.SECONDS.update(seconds)
    try:
        scheduler = SlowestFirst(_Config(), None, exclusive=exclusive)
        nodes = [_Node("gw0"), _Node("gw1")]
        for node in nodes:
            scheduler.add_node(node)
            scheduler.add_node_collection(node, collection)
        scheduler.schedule()
    finally:
        tests.schedule.SECONDS.clear()
        tests.schedule.SECONDS.update(old)
    return scheduler, nodes


def _first_units(collection: list[str], nodes: list[_Node]) -> list[str]:
    """The unit each worker was sent first."""
    return [collection[node.sent[0]].rsplit("::", 1)[0] for node in nodes]


def test_loadscope_runs_with_the_slowest_first_scheduler() -> None:
    from tests.conftest import pytest_xdist_make_scheduler

    scheduler = pytest_xdist_make_scheduler(_Config(), None)  # type: ignore[arg-type]
    assert isinstance(scheduler, SlowestFirst) and scheduler.exclusive == RAY_MODULES
    other = _Config()
    other.getvalue = lambda name: {"tx": ["2*popen"], "dist": "load"}[name]  # type: ignore[method-assign]
    assert pytest_xdist_make_scheduler(other, None) is None  # type: ignore[arg-type]


def test_the_slowest_units_go_out_first() -> None:
    """xdist alone would hand out ``many.py`` first (the most tests); the measured
    seconds put the two slow units first, one on each worker."""
    collection = [
        *(f"tests/many.py::test_{i}" for i in range(8)),
        "tests/slow.py::test_a",
        "tests/docs.py::TestPage_x::test_run",
        "tests/docs.py::TestPage_y::test_run",
    ]
    seconds = {"tests/slow.py": 300.0, "tests/docs.py::TestPage_y": 200.0}
    _, nodes = _scheduled(collection, seconds)
    assert _first_units(collection, nodes) == ["tests/slow.py", "tests/docs.py::TestPage_y"]


def test_a_second_ray_unit_waits_while_other_work_remains() -> None:
    collection = ["tests/ray1.py::test_a", "tests/ray2.py::test_a", "tests/quick.py::test_a"]
    seconds = {"tests/ray1.py": 100.0, "tests/ray2.py": 90.0, "tests/quick.py": 10.0}
    ray = frozenset({"tests/ray1.py", "tests/ray2.py"})
    _, nodes = _scheduled(collection, seconds, exclusive=ray)
    assert _first_units(collection, nodes) == ["tests/ray1.py", "tests/quick.py"]
    _, nodes = _scheduled(collection, seconds)  # not exclusive: slowest first alone
    assert _first_units(collection, nodes) == ["tests/ray1.py", "tests/ray2.py"]


def test_each_docs_page_is_a_unit_of_its_own() -> None:
    """tests/test_docs_run.py holds a class per page that runs (per block, for the pages
    whose blocks run apart): a unit each, every block that runs (neither skipped nor
    covered) in one of them."""
    import tests.test_docs_run as docs_run

    classes = {n: c for n, c in vars(docs_run).items() if n.startswith("TestPage_")}
    units = docs_run._units()
    assert sorted(classes) == sorted(name for name, _ in units)
    assert len(units) > len(docs_run._RUN_PAGES) >= 10
    ran = [b for _, blocks in units for b in blocks]
    assert sorted(b.name for b in ran) == sorted(b.name for b in docs_run._BLOCKS if b.runs)


def test_every_timed_unit_exists() -> None:
    """The table names units that are still there: a module, or a module's class."""
    import importlib

    from tests.schedule import SECONDS

    assert SECONDS, "the table of slow units is empty"
    for scope in SECONDS:
        module, _, cls = scope.partition("::")
        assert (REPO / module).is_file(), f"{scope}: no such module"
        if cls:
            loaded = importlib.import_module(module.removesuffix(".py").replace("/", "."))
            assert hasattr(loaded, cls), f"{scope}: no such class"


def test_the_table_is_made_from_a_durations_report() -> None:
    from tests.schedule import scope_seconds

    report = """============================= slowest 60 durations =============================
653.32s call     tests/test_docs_run.py::TestPage_docs_lookalike_2::test_the_sh_blocks_run
190.05s setup    tests/test_experiment.py::test_the_experiment_writes_every_table_and_figure
20.00s call     tests/test_experiment.py::test_other[a::b]
10.00s teardown tests/test_experiment.py::test_other[x]
30.00s call     tests/localizer/test_quick.py::test_one
(4 durations < 0.005s hidden.  Use -vv to show these durations.)
"""
    assert scope_seconds(report) == {
        "tests/test_docs_run.py::TestPage_docs_lookalike_2": 653.32,
        "tests/test_experiment.py": 220.05,
        "tests/localizer/test_quick.py": 30.0,
    }
    assert list(scope_seconds(report, least_s=200.0)) == [
        "tests/test_docs_run.py::TestPage_docs_lookalike_2",
        "tests/test_experiment.py",
    ]
