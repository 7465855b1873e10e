"""The order in which ``pytest -n N --dist loadscope`` hands out its work units.

xdist's ``loadscope`` groups the tests by module (by class for a class's methods) and
hands the units out largest first by test count. The time a unit takes has little to do
with its count: one docs page that records a run outweighs a module of 150 quick
checks. Handed out last, a long unit runs alone at the end while the other workers sit
idle. :class:`SlowestFirst` hands out the units slowest first (the longest processing
time rule), by the seconds :data:`SECONDS` gives, measured on the 2-core machine; the
units it does not name follow, largest first by count, as xdist orders them. And it
keeps two units that start Ray (:data:`tests.conftest.RAY_MODULES`) from running at
once where another unit can run instead: the second would only wait for the first's
lock (tests/conftest.py).

The figures need not be exact: they only order the work. When a unit's cost changes
much, refresh them from a run's report: ``python3 -m pytest -q -n auto --dist loadscope
--durations=0 > LOG``, then ``python3 -m tests.schedule LOG`` prints the table's lines
(tests/test_parallel.py checks that each names a unit that exists).
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Any

from xdist.scheduler import LoadScopeScheduling

#: Seconds the slow units took (the sum of their tests' durations over 25 s) in a run
#: of ``pytest -n auto --dist loadscope --durations=60`` on the 2-core machine, shared
#: with other work (about three times CI's times; only their order counts here). The
#: docs pages split in blocks (tests/test_docs_run.py) were timed in a serial run of
#: those blocks alone, the machine about as busy. Units made cheaper since are scaled by
#: their CPU seconds (user + system) after against before, each measured alone; units
#: that start Ray by their wall time (Ray's daemons are not the test's children, so
#: its CPU count misses them). Docs units the table did not have, and those whose
#: blocks moved (a covered block no longer runs; the blocks after it take its place),
#: are their CPU seconds alone times 3.38: docs_simulator_2's 315 s against its 93.3 s
#: of CPU, measured when that unit still held the page's first bench_explore block.
SECONDS: dict[str, float] = {
    "tests/recorder/test_record_command.py": 435.0,
    "tests/sim/test_controller.py": 288.0,
    "tests/test_docs_run.py::TestPage_docs_lookalike_2": 348.0,
    "tests/replay/test_view.py": 166.0,
    "tests/replay/test_replay.py": 171.0,
    "tests/test_experiment.py": 190.0,
    "tests/batch/test_batch_ray.py": 190.0,
    "tests/test_faults.py": 190.0,
    "tests/recorder/test_explore_runs.py": 141.0,
    "tests/test_docs_run.py::TestPage_docs_simulator_3": 167.0,
    "tests/test_docs_run.py::TestPage_docs_simulator_2": 160.0,
    "tests/test_docs_run.py::TestPage_docs_simulator_4": 154.0,
    "tests/test_docs_run.py::TestPage_docs_performance": 152.0,
    "tests/test_docs_run.py::TestPage_docs_ros2": 136.0,
    "tests/test_docs_run.py::TestPage_docs_lookalike_3": 65.0,
    "tests/recorder/test_truth_poisoning.py": 51.0,
    "tests/test_docs_run.py::TestPage_docs_lookalike_1": 94.0,
    "tests/test_docs_run.py::TestPage_docs_stuck": 79.0,
    "tests/ros2/test_import.py": 66.0,
    "tests/test_docs_run.py::TestPage_docs_lighting_2": 74.0,
    "tests/test_packaging.py": 42.0,
    "tests/test_docs_run.py::TestPage_docs_recorder_2": 62.0,
    "tests/test_docs_run.py::TestPage_docs_lighting_1": 57.0,
    "tests/test_docs_run.py::TestPage_docs_lighting_3": 54.0,
    "tests/test_docs_run.py::TestPage_docs_localizer": 55.0,
    "tests/test_fuzz.py": 53.0,
    "tests/test_docs_run.py::TestPage_docs_simulator_1": 51.0,
    "tests/localizer/test_twoview_stages.py": 47.0,
    "tests/test_docs_run.py::TestPage_docs_replay": 43.0,
    "tests/test_docs_run.py::TestPage_docs_exploration": 42.0,
    "tests/test_docs_run.py::TestPage_docs_imagesets": 41.0,
    "tests/test_docs_run.py::TestPage_docs_view": 40.0,
    "tests/test_docs_run.py::TestPage_docs_recorder_1": 40.0,
    "tests/recorder/test_obstacle_runs.py": 36.0,
}


def cost(scope: str, tests: int) -> tuple[float, int]:
    """The sort key of a unit: its measured seconds, then its count of tests."""
    return (SECONDS.get(scope, 0.0), tests)


class SlowestFirst(LoadScopeScheduling):
    """``loadscope``, its units handed out slowest first, units that start Ray one at
    a time where there is other work."""

    def __init__(self, config: Any, log: Any = None, exclusive: Collection[str] = ()) -> None:
        super().__init__(config, log)
        self.exclusive = frozenset(exclusive)

    def _exclusive_elsewhere(self, node: Any) -> bool:
        """Whether a node other than ``node`` has a unit of :attr:`exclusive` not done."""
        return any(
            scope in self.exclusive and not all(unit.values())
            for other, work in self.assigned_work.items()
            if other is not node
            for scope, unit in work.items()
        )

    def _assign_work_unit(self, node: Any) -> None:
        order = sorted(self.workqueue, key=lambda s: cost(s, len(self.workqueue[s])), reverse=True)
        if self._exclusive_elsewhere(node):
            others = [s for s in order if s not in self.exclusive]
            order = others + [s for s in order if s in self.exclusive]
        for scope in reversed(order):
            self.workqueue.move_to_end(scope, last=False)
        super()._assign_work_unit(node)


def scope_seconds(durations: str, least_s: float = 25.0) -> dict[str, float]:
    """The seconds of each unit in the lines of pytest's ``--durations`` report
    (``12.34s call     tests/x.py::Class::test_y[param]``), summed over setup, call and
    teardown, for the units of at least ``least_s``; slowest first."""
    found: dict[str, float] = {}
    for line in durations.splitlines():
        parts = line.split()
        if len(parts) != 3 or not parts[0].endswith("s") or "::" not in parts[2]:
            continue
        try:
            seconds = float(parts[0][:-1])
        except ValueError:
            continue
        nodeid = parts[2].split("[", 1)[0]
        scope = nodeid.rsplit("::", 1)[0]
        found[scope] = found.get(scope, 0.0) + seconds
    return dict(sorted(((s, t) for s, t in found.items() if t >= least_s), key=lambda i: -i[1]))


if __name__ == "__main__":
    # python -m tests.schedule LOG: the table above, from a run's --durations report.
    import sys
    from pathlib import Path

    for scope, seconds in scope_seconds(Path(sys.argv[1]).read_text()).items():
        print(f'    "{scope}": {seconds:.0f}.0,')
