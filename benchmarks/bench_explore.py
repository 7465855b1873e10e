"""Map-driven exploration on networks with loops: coverage, correctness, distance.

    python benchmarks/bench_explore.py [--suite must|loops50|paper|all] [--resolution PX]
                                       [--jobs N] [--explore map|right-hand]
                                       [--alike F] [--first K] [--count N]
                                       [--no-odometry-check] [--no-probe-moves]
                                       [--tilt-deg DEG] [--obstacles N] [--hypotheses K]
                                       [--keep DIR]

Each run is ``pipemap record`` (autonomous, the online localizer choosing exits from
its map) into a temporary log, then ``pipemap score`` of that log. One line per run:

* how the run ended (``finished``: every known pipe traversed and back at the start);
* coverage: true nodes swept and true pipes driven, of the network's;
* the map (``correct``, ``partial``, ``wrong``) and its ports (``ok`` when every map
  edge joins the true pipe ends);
* the distance driven against the network's total pipe length, and the pipe
  traversals against the number of pipes (Trémaux drives each pipe at most twice,
  and the way home adds at most one more crossing of each pipe on it);
* for the port tolerance: the largest misfit of a correct revisit's exits with its
  junction's ports (rad); for the odometry check: the largest distance between a
  correct revisit's dead-reckoned position and the first visit's (m), and the
  smallest between two different junctions with as many pipes (m).

Suites: ``must`` is the issue's list (``paper`` from all 7 starts, ``grid:3x3``,
``grid:4x4``, ``grid:5x5``, ``random:N`` for N = 10, 15, ..., 40); ``loops50`` is
50 seeded loop networks, ``random:N`` with N = 10 + k mod 21 and seed k, k = 0..49;
``paper`` is the paper's network from its 7 starts. ``--alike F`` records look-alike
worlds (``pipemap record --alike F``: docs/lookalike.md); the line then ends with the
decisions that went wrong (false merges, false new junctions). ``--first K --count N``
runs N of the suite's runs from the K-th. ``--no-odometry-check`` records and replays
with the localizer's odometry check off (the localizer before it existed);
``--hypotheses 1`` with one map (no competing hypotheses: docs/lookalike.md), and the
line's ``deferred`` counts the decisions the localizer kept open among look-alikes.
``--no-probe-moves`` records with the robot making none of the probe moves active
vision asks for (``pipemap record --no-probe-moves``); ``--tilt-deg`` and
``--obstacles`` are ``pipemap record``'s. Each line ends with the probe sweeps the
robot made of those the localizer asked for. ``--keep DIR`` keeps each run's log as
``DIR/<spec>-seed<k>[-from-<start>].mcap`` (``random:16`` seed 3: ``random16-seed3.mcap``)
instead of recording into a temporary folder, to be replayed and scored again later
(``pipemap score LOG --hypotheses 1``).
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

from pipemap import __version__

#: ``pipemap record``'s default. At 96 px the two-view check misses some revisits of
#: crosses seen from another pipe (34 inliers against the 48 it asks for), and those
#: runs end ``map inconsistent``.
RESOLUTION_PX = 400


@dataclass(frozen=True)
class Case:
    """One run: network spec, seed, start (``None``: the entry)."""

    spec: str
    seed: int = 0
    start: str | None = None

    @property
    def name(self) -> str:
        start = "" if self.start is None else f" from {self.start}"
        return f"{self.spec} seed {self.seed}{start}"


@dataclass(frozen=True)
class Outcome:
    """What one run gave."""

    case: Case
    status: str
    nodes: tuple[int, int]
    pipes: tuple[int, int]
    map_status: str
    ports_correct: bool | None
    visits: int
    driven_m: float
    network_m: float
    traversals: int
    residual_rad: float
    scan_error_rad: float
    odometry_same_m: float
    odometry_other_m: float
    wall_s: float
    false_merges: int = 0
    false_new: int = 0
    probes_made: int = 0
    probes_asked: int = 0
    deferred: int = 0
    still_open: int = 0

    @property
    def covered(self) -> bool:
        return self.nodes[0] == self.nodes[1] and self.pipes[0] == self.pipes[1]

    def line(self) -> str:
        ports = {True: "ok", False: "WRONG", None: "-"}[self.ports_correct]
        return (
            f"{self.case.name:<28} {self.status:<17} nodes {self.nodes[0]:>2}/{self.nodes[1]:<2} "
            f"pipes {self.pipes[0]:>2}/{self.pipes[1]:<2} map {self.map_status:<7} ports "
            f"{ports:<5} visits {self.visits:>3}"
            f"  driven/length {self.driven_m / self.network_m:4.2f}"
            f"  traversals/pipes {self.traversals / max(1, self.pipes[1]):4.2f}"
            f"  scan {self.scan_error_rad:.3f} residual {self.residual_rad:.3f}"
            f"  odo same {self.odometry_same_m:.2f} "
            f"other {self.odometry_other_m:.2f}  {self.wall_s:5.1f} s"
            f"  false merge {self.false_merges} false new {self.false_new}"
            f"  deferred {self.deferred} open {self.still_open}"
            f"  probes {self.probes_made}/{self.probes_asked}"
        )


def run_case(
    case: Case,
    resolution_px: int,
    explore: str,
    alike: float = 0.0,
    odometry_check: bool = True,
    probe_moves: bool = True,
    tilt_deg: float = 0.0,
    obstacles: int = 0,
    hypotheses: int = 8,
    keep: Path | None = None,
) -> Outcome:
    """Record ``case``, replay and score it."""
    from pipemap.localizer import LocalizerConfig
    from pipemap.recorder import Explore, RecordSettings, record_run
    from pipemap.replay import FileSource, replay, score_replay
    from pipemap.replay.coverage import true_network
    from pipemap.sim.network import build_network

    network = build_network(case.spec, seed=case.seed)
    settings = RecordSettings(
        network=case.spec,
        start=case.start,
        seed=case.seed,
        resolution_px=resolution_px,
        explore=Explore(explore),
        alike=alike,
        odometry_check=odometry_check,
        probe_moves=probe_moves,
        tilt_rad=math.radians(tilt_deg),
        obstacles=obstacles,
        hypotheses=hypotheses,
    )
    began = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.mcap" if keep is None else keep / log_name(case)
        recorded = record_run(path, settings, network, __version__)
        source = FileSource(path)
        config = LocalizerConfig(odometry_check=odometry_check, hypotheses=hypotheses)
        result = replay(source, config)
        report = score_replay(result, source, settings.threshold)
        truth = true_network(source)
    wall = time.perf_counter() - began
    assert truth is not None and report.coverage is not None
    true_nodes = [v.true_node for v in report.visits]
    traversals = sum(
        1
        for a, b in zip(true_nodes, true_nodes[1:], strict=False)
        if (min(a, b), max(a, b)) in truth.pipes
    )
    residuals = [
        v.decision.port_residual_rad
        for v, s in zip(result.visits, report.visits, strict=True)
        if s.outcome == "correct_known" and v.decision.port_residual_rad is not None
    ]
    same, other = _odometry(result, true_nodes, truth)
    scan = _scan_error(result, source, truth)
    cov = report.coverage
    return Outcome(
        case,
        recorded.status,
        (cov.nodes_visited, cov.nodes_total),
        (cov.pipes_traversed, cov.pipes_total),
        report.map_status,
        report.ports_correct,
        len(report.visits),
        recorded.distance_m,
        truth.total_length_m(),
        traversals,
        max(residuals, default=0.0),
        scan,
        same,
        other,
        wall,
        report.counts()["false_merge"],
        report.counts()["false_new"],
        probes_made=sum(p.similarity is not None for v in result.visits for p in v.decision.probes),
        probes_asked=sum(len(v.decision.probes) for v in result.visits),
        deferred=len(report.deferred_visits),
        still_open=len(report.open_visits),
    )


def log_name(case: Case) -> str:
    """The file name ``--keep`` gives a run's log."""
    start = "" if case.start is None else f"-from-{case.start}"
    return f"{case.spec.replace(':', '')}-seed{case.seed}{start}.mcap"


def _scan_error(result, source, truth) -> float:  # type: ignore[no-untyped-def]
    """The largest angle between an exit the scan found and its true pipe, with the
    robot's true heading (the scan's share of a revisit's port misfit)."""
    from pipemap.localizer import wrap_angle_rad
    from pipemap.replay.score import true_sweeps

    truths = true_sweeps(source)
    worst = 0.0
    for v in result.visits:
        t = truths[v.sweep_id]
        if v.exits is None or v.exits.exits_rad is None or t.node not in truth.positions:
            continue
        heading = t.yaw_rad - result.camera_angles[v.sweep_id]
        pipes = list(truth.headings(t.node).values())
        for e in v.exits.exits_rad:
            worst = max(worst, min(abs(wrap_angle_rad(heading + e - p)) for p in pipes))
    return worst


def _odometry(result, true_nodes: list[str], truth) -> tuple[float, float]:  # type: ignore[no-untyped-def]
    """Largest dead-reckoning distance between visits of one junction, smallest
    between first visits of two junctions with as many pipes."""
    first: dict[str, tuple[float, float]] = {}
    same = 0.0
    for v, node in zip(result.visits, true_nodes, strict=True):
        if v.exits is None:
            continue
        here = (v.exits.x_m, v.exits.y_m)
        if node in first:
            same = max(same, math.dist(here, first[node]))
        else:
            first[node] = here
    other = math.inf
    labels = sorted(first)
    for i, a in enumerate(labels):
        for b in labels[i + 1 :]:
            if len(truth.headings(a)) == len(truth.headings(b)):
                other = min(other, math.dist(first[a], first[b]))
    return same, other


def cases(suite: str) -> list[Case]:
    """The runs of a suite."""
    must = [Case("paper", 0, s) for s in "SABCDEF"]
    must += [Case(f"grid:{n}x{n}") for n in (3, 4, 5)]
    must += [Case(f"random:{n}") for n in range(10, 41, 5)]
    loops = [Case(f"random:{10 + k % 21}", k) for k in range(50)]
    paper = must[:7]
    return {"must": must, "loops50": loops, "paper": paper, "all": must + loops}[suite]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", choices=["must", "loops50", "paper", "all"], default="all")
    parser.add_argument("--resolution", type=int, default=RESOLUTION_PX)
    parser.add_argument("--jobs", type=int, default=1)
    parser.add_argument("--explore", choices=["map", "right-hand"], default="map")
    parser.add_argument("--first", type=int, default=0, help="skip the suite's first runs")
    parser.add_argument("--count", type=int, default=None, help="run this many at most")
    parser.add_argument("--alike", type=float, default=0.0, help="record --alike (0)")
    parser.add_argument(
        "--no-odometry-check", action="store_true", help="the localizer's odometry check off"
    )
    parser.add_argument(
        "--no-probe-moves", action="store_true", help="the robot makes no probe moves"
    )
    parser.add_argument("--tilt-deg", type=float, default=0.0, help="record --tilt-deg (0)")
    parser.add_argument("--obstacles", type=int, default=0, help="record --obstacles (0)")
    parser.add_argument(
        "--hypotheses", type=int, default=8, help="the localizer's live maps at most (8)"
    )
    parser.add_argument(
        "--keep", type=Path, default=None, metavar="DIR", help="keep each run's log in DIR"
    )
    args = parser.parse_args()
    if args.keep is not None:
        args.keep.mkdir(parents=True, exist_ok=True)
    todo = cases(args.suite)[args.first :]
    todo = todo if args.count is None else todo[: args.count]
    print(
        f"# bench_explore: {len(todo)} runs, {args.resolution} px, explore {args.explore}, "
        f"alike {args.alike:g}, odometry check "
        f"{'off' if args.no_odometry_check else 'on'}, probe moves "
        f"{'off' if args.no_probe_moves else 'on'}, tilt {args.tilt_deg:g} deg, "
        f"{args.obstacles} obstacle(s), hypotheses {args.hypotheses}, {args.jobs} job(s)",
        flush=True,
    )
    outcomes: list[Outcome] = []
    with ProcessPoolExecutor(max_workers=args.jobs) as pool:
        futures = [
            pool.submit(
                run_case,
                c,
                args.resolution,
                args.explore,
                args.alike,
                not args.no_odometry_check,
                not args.no_probe_moves,
                args.tilt_deg,
                args.obstacles,
                args.hypotheses,
                args.keep,
            )
            for c in todo
        ]
        for future in futures:
            outcome = future.result()
            outcomes.append(outcome)
            print(outcome.line(), flush=True)
    _summary(outcomes)
    return 0


def _summary(outcomes: list[Outcome]) -> None:
    n = len(outcomes)
    finished = sum(o.status == "finished" for o in outcomes)
    watchdog = sum(o.status in ("stuck", "left the pipe", "time limit") for o in outcomes)
    covered = sum(o.covered for o in outcomes)
    correct = sum(o.map_status == "correct" for o in outcomes)
    ports = sum(o.ports_correct is True for o in outcomes)
    ratios = [o.driven_m / o.network_m for o in outcomes]
    traversals = [o.traversals / o.pipes[1] for o in outcomes]
    print(f"# {n} runs: {finished} finished, {watchdog} ended by the watchdog")
    print(
        f"# every node and pipe covered: {covered}/{n}; map correct: {correct}/{n}; "
        f"ports correct: {ports}/{n}"
    )
    print(
        f"# driven / total pipe length: mean {statistics.fmean(ratios):.2f}, "
        f"max {max(ratios):.2f}; pipe traversals / pipes: mean "
        f"{statistics.fmean(traversals):.2f}, max {max(traversals):.2f}"
    )
    print(
        f"# exit scan against the true pipes: max {max(o.scan_error_rad for o in outcomes):.3f} "
        f"rad; port misfit of correct revisits: max "
        f"{max(o.residual_rad for o in outcomes):.3f} rad; "
        f"odometry: same junction at most {max(o.odometry_same_m for o in outcomes):.2f} m apart, "
        f"different junctions of one kind at least "
        f"{min(o.odometry_other_m for o in outcomes):.2f} m"
    )
    print(
        f"# decisions wrong: {sum(o.false_merges for o in outcomes)} false merges, "
        f"{sum(o.false_new for o in outcomes)} false new junctions; "
        f"{sum(o.deferred for o in outcomes)} deferred, "
        f"{sum(o.still_open for o in outcomes)} still open at the end; probe sweeps made "
        f"{sum(o.probes_made for o in outcomes)} of {sum(o.probes_asked for o in outcomes)} "
        "asked for"
    )
    print(f"# wall time: {sum(o.wall_s for o in outcomes):.0f} s in all")


if __name__ == "__main__":
    sys.exit(main())
