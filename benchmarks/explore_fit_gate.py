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

import math
import sys
from pathlib import Path

from pipemap.localizer import Decision, ExploreConfig, LocalizerConfig, MapExplorer, TopoMap
from pipemap.localizer.odometry import DeadReckoning
from pipemap.localizer.ports import clockwise_ports

sys.path.insert(0, str(Path(__file__).resolve().parent))

from heading_fit_gate import each_log, scanned_visits  # noqa: E402


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
    rows = [row for row in scanned_visits(log) if row[3]]  # a scan that found exits
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


def _line(row: dict[str, object]) -> str:
    first = row["first_fitted"]
    alarms = "; ".join(
        f"{name}: new {_list(row[name + '_new'])}, known {_list(row[name + '_known'])}"
        for name in ("raw", "fitted")
    )
    used = first if first is not None else math.nan
    return (
        f"{row['log']}: {row['visits']} visits, fit used from visit {used}; false alarms, {alarms}"
    )


def main(argv: list[str] | None = None) -> int:
    return each_log(argv, __doc__.split("\n\n")[0], gate, _line)


if __name__ == "__main__":
    sys.exit(main())
