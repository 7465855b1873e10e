"""What the heading fit does to the odometry check on recorded runs.

    python benchmarks/heading_fit_gate.py LOG [LOG ...] [--json]

For each pipemap log: every visit's dead reckoning and odometer (its first exit
scan) and, for scoring only, the true junction of each visit (``/truth``). The
visits are fed in order to two :class:`localizer.odometry.DeadReckoning`, one with
``odometry_heading_bias`` off (the check as it was) and one with it on; at each true
revisit both are asked which known junctions lie inside the check, and then the
revisit is closed in both, as a localizer deciding every visit right would. So this
measures the check alone, not the decisions (``pipemap score LOG`` replays those).
One line (or one JSON object) per log: visits, revisits, at how many revisits the
fit was used (``DeadReckoning.fitted``), at how many the set inside the check
differs, the true junction outside the check (off / on), other junctions inside it
summed over the revisits (off / on), the largest corrected offset of a revisit
once the fit is used, and the wall time of a refit at each revisit (median and most)
with the number of knots at the end.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from collections.abc import Callable

from pipemap.localizer import LocalizerConfig
from pipemap.localizer.odometry import DeadReckoning
from pipemap.recorder import Topic
from pipemap.recorder.schemas.pipemap_log_pb2 import NodeEvent, TrueSweep
from pipemap.replay import StreamSource


def scanned_visits(log: str) -> list[tuple[float, float, float, tuple[float, ...], str]]:
    """Each visit's dead reckoning (x, y), odometer, exits and true junction, in order."""
    source = StreamSource(log, (Topic.NODE, Topic.TRUE_SWEEP))
    scans: dict[int, tuple[float, float, float, tuple[float, ...]]] = {}
    for m in source.robot_stream():
        if m.topic == Topic.NODE:
            event = NodeEvent.FromString(m.data)
            if event.kind == NodeEvent.EXITS and event.visit_id not in scans:
                where = (event.x_estimate_m, event.y_estimate_m, event.odometer_m)
                scans[event.visit_id] = (*where, tuple(event.exits_rad))
    truth: dict[int, str] = {}
    for m in source.truth():
        if m.topic == Topic.TRUE_SWEEP:
            sweep = TrueSweep.FromString(m.data)
            truth.setdefault(sweep.visit_id, sweep.node)
    return [(*scans[v], truth[v]) for v in sorted(scans) if v in truth]


def visits(log: str) -> list[tuple[float, float, float, str]]:
    """Each visit's dead reckoning (x, y), odometer and true junction, in order."""
    return [(x, y, s, node) for x, y, s, _, node in scanned_visits(log)]


def gate(log: str) -> dict[str, object]:
    """The check with the fit off and on at every true revisit of ``log``."""
    checks = {on: DeadReckoning(LocalizerConfig(odometry_heading_bias=on)) for on in (False, True)}
    ids: dict[str, int] = {}
    out = {"log": log, "visits": 0, "revisits": 0, "fitted": 0, "differ": 0}
    missed = {False: 0, True: 0}
    others = {False: 0, True: 0}
    worst = 0.0
    fits: list[float] = []
    for x, y, odometer, node in visits(log):
        out["visits"] += 1
        for check in checks.values():
            check.at((x, y), odometer)
        if node not in ids:
            ids[node] = len(ids)
            for check in checks.values():
                check.remember(ids[node])
            continue
        out["revisits"] += 1
        i = ids[node]
        inside = {on: {j for j in ids.values() if c.near(j)} for on, c in checks.items()}
        for on in checks:
            missed[on] += i not in inside[on]
            others[on] += len(inside[on] - {i})
        out["differ"] += inside[False] != inside[True]
        if checks[True].fitted():
            out["fitted"] += 1
            worst = max(worst, checks[True].offset_m(i) or 0.0)
        checks[False].closed(i)
        start = time.perf_counter()
        checks[True].closed(i)
        fits.append(1000.0 * (time.perf_counter() - start))
    out.update(
        missed_off=missed[False],
        missed_on=missed[True],
        others_off=others[False],
        others_on=others[True],
        worst_fitted_offset_m=round(worst, 3),
        fit_ms_median=round(statistics.median(fits), 3) if fits else None,
        fit_ms_max=round(max(fits), 3) if fits else None,
        knots=len(checks[True].bias.knots),
    )
    return out


def each_log(
    argv: list[str] | None,
    description: str,
    measure: Callable[[str], dict[str, object]],
    line: Callable[[dict[str, object]], str],
) -> int:
    """Run ``measure`` on each LOG of the command line and print each row as ``line``
    says, or (``--json``) as one JSON object a line."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("logs", nargs="+", metavar="LOG")
    parser.add_argument("--json", action="store_true", help="one JSON object a line")
    args = parser.parse_args(argv)
    for log in args.logs:
        row = measure(log)
        print(json.dumps(row) if args.json else line(row), flush=True)
    return 0


def _line(row: dict[str, object]) -> str:
    log = row["log"]
    return (
        f"{log}: {row['visits']} visits, {row['revisits']} revisits, fit used at "
        f"{row['fitted']}, check differs at {row['differ']}; true junction outside "
        f"{row['missed_off']}/{row['missed_on']}, others inside "
        f"{row['others_off']}/{row['others_on']} (fit off/on); worst corrected "
        f"offset {row['worst_fitted_offset_m']} m; a refit {row['fit_ms_median']} ms "
        f"median, {row['fit_ms_max']} ms at most ({row['knots']} knots)"
    )


def main(argv: list[str] | None = None) -> int:
    return each_log(argv, __doc__.split("\n\n")[0], gate, _line)


if __name__ == "__main__":
    sys.exit(main())
