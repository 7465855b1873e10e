"""What the heading fit does to the map explorer's odometry checks on recorded runs.

    python benchmarks/explore_fit_gate.py LOG [LOG ...] [--json]

For each pipemap log: every visit's dead reckoning, odometer and exits (its first
exit scan) and, to stand in for a localizer that decides every visit right, the true
junction of each visit (``/truth``, used for nothing else). The visits are fed in
order to a :class:`localizer.odometry.DeadReckoning` (as :meth:`Localizer.localize`
feeds it: a new junction remembered, a revisit closing its loop) and to two
:class:`localizer.explore.MapExplorer`: one checking raw dead reckoning (as before
the explorer read the fit) and one handed that dead reckoning
(``MapExplorer.odometry``). Since every decision is right, each odometry sign either
explorer reports is a false alarm: ``new`` (a new junction put on a known one's
place) or ``known`` (a revisit too far from where its junction was). One line (or
one JSON object) per log: visits, the first visit at which the fit is used, and each
explorer's false alarms of each kind with the visits they came at. The explorers'
other signs (ports, routes) are not counted: without images the stand-in gives no
exit ports on revisits.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

from pipemap.localizer import Decision, ExploreConfig, LocalizerConfig, MapExplorer, TopoMap
from pipemap.localizer.odometry import DeadReckoning
from pipemap.localizer.ports import clockwise_ports
from pipemap.recorder import Topic
from pipemap.recorder.schemas.pipemap_log_pb2 import NodeEvent, TrueSweep
from pipemap.replay import StreamSource

Visit = tuple[float, float, float, tuple[float, ...], str]


def visits(log: str) -> list[Visit]:
    """Each visit's dead reckoning (x, y), odometer, exits and true junction, in order."""
    source = StreamSource(log, (Topic.NODE, Topic.TRUE_SWEEP))
    scans: dict[int, tuple[float, float, float, tuple[float, ...]]] = {}
    for m in source.robot_stream():
        if m.topic == Topic.NODE:
            event = NodeEvent.FromString(m.data)
            if event.kind == NodeEvent.EXITS and event.visit_id not in scans:
                exits = tuple(event.exits_rad)
                scans[event.visit_id] = (
                    event.x_estimate_m,
                    event.y_estimate_m,
                    event.odometer_m,
                    exits,
                )
    truth: dict[int, str] = {}
    for m in source.truth():
        if m.topic == Topic.TRUE_SWEEP:
            sweep = TrueSweep.FromString(m.data)
            truth.setdefault(sweep.visit_id, sweep.node)
    return [(*scans[v], truth[v]) for v in sorted(scans) if v in truth and scans[v][3]]


def _alarms(explorer: MapExplorer, seen: int, visit: int, out: dict[str, list[int]]) -> None:
    for text in explorer.inconsistencies[seen:]:
        for sign in text.split("; "):
            if sign.endswith("by odometry"):
                out["new" if "from known junction" in sign else "known"].append(visit)


def gate(log: str) -> dict[str, object]:
    """Both explorers' odometry alarms over ``log``, every visit decided right."""
    odometry = DeadReckoning(LocalizerConfig())
    config = ExploreConfig(max_inconsistencies=10**9)
    explorers = {"raw": MapExplorer(config), "fitted": MapExplorer(config, odometry=odometry)}
    maps = {name: TopoMap() for name in explorers}
    alarms: dict[str, dict[str, list[int]]] = {n: {"new": [], "known": []} for n in explorers}
    ids: dict[str, int] = {}
    first_fitted = None
    rows = visits(log)
    for index, (x, y, odometer, exits, label) in enumerate(rows, 1):
        odometry.at((x, y), odometer)
        known = label in ids
        if known:
            node, ports, exit_ports = ids[label], None, None
            odometry.closed(node)
        else:
            node = ids[label] = len(ids)
            ports, exit_ports = clockwise_ports(exits)
            odometry.remember(node)
        if first_fitted is None and odometry.fitted():
            first_fitted = index
        decision = Decision(
            node, known, None, 0.0, None, None, exits_rad=exits, exit_ports=exit_ports
        )
        for name, explorer in explorers.items():
            maps[name].visit(node, ports, None, odometer)
            seen = len(explorer.inconsistencies)
            explorer.step(maps[name], decision, x, y, odometer)
            _alarms(explorer, seen, index, alarms[name])
    out: dict[str, object] = {"log": log, "visits": len(rows), "first_fitted": first_fitted}
    for name, kinds in alarms.items():
        for kind, at in kinds.items():
            out[f"{name}_{kind}"] = at
    return out


def _list(at: object) -> str:
    assert isinstance(at, list)
    return f"{len(at)}" + (f" (visits {', '.join(map(str, at))})" if at else "")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("logs", nargs="+", metavar="LOG")
    parser.add_argument("--json", action="store_true", help="one JSON object a line")
    args = parser.parse_args(argv)
    for log in args.logs:
        row = gate(log)
        if args.json:
            print(json.dumps(row), flush=True)
            continue
        first = row["first_fitted"]
        print(
            f"{log}: {row['visits']} visits, fit used from visit "
            f"{first if first is not None else math.nan}; false alarms, raw: new "
            f"{_list(row['raw_new'])}, known {_list(row['raw_known'])}; fitted: new "
            f"{_list(row['fitted_new'])}, known {_list(row['fitted_known'])}",
            flush=True,
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
