"""Getting unstuck: seeded runs with floor deposits or motor cut-outs, how each ended.

    nice -n 10 python benchmarks/bench_stuck.py [--runs 20] [--obstacles 3]
        [--motor-faults 0] [--resolution 64] [--networks grid:2x3,random:8,paper,grid:3x3]
        [--out DIR] [--ablate-waits]

Run k records ``pipemap record --network NETWORKS[k % len] --seed k --obstacles N
--motor-faults M --resolution R`` (the map-driven robot, the lamp on), then scores the
log (replay
from ``/robot`` alone, against the truth). Per run it prints how the run ended, the
deposits of each kind, the stalls the robot met, how many it got past, the pipes it
gave up (and how many of those marks are truly blocked, false, or missed), the map's
status, the simulated time against the time limit and the wall time. A run hangs if
it neither ends nor reaches its time limit; the watchdog is the last resort. Not a
timed test: numbers for docs/stuck.md.

``--ablate-waits`` instead runs each seed's exploration in the simulator alone (no
log, no localizer: the paper's right-hand rule, 32 px) twice, with the robot waiting
for its motors when it cannot back off (the default) and without, and prints the
pipes each gave up and how each ended: what waiting for the motors earns.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from pipemap.recorder import RecordSettings, Topic, record_run
from pipemap.recorder.messages import blocked_visit
from pipemap.recorder.schemas import Log
from pipemap.replay import FileSource
from pipemap.replay.score import score
from pipemap.sim.controller import default_time_limit_ns
from pipemap.sim.network import build_network
from pipemap.sim.obstacles import ObstacleKind


def _run(network: str, seed: int, args: argparse.Namespace, folder: Path) -> dict:
    net = build_network(network, seed=seed)
    settings = RecordSettings(
        network,
        seed=seed,
        resolution_px=args.resolution,
        obstacles=args.obstacles,
        motor_faults=args.motor_faults,
    )
    kinds = [o.kind for o in settings.deposits(net)]
    path = folder / f"{network.replace(':', '_')}_s{seed}.mcap"
    start = time.perf_counter()
    result = record_run(path, settings, net, "bench", overwrite=True)
    wall = time.perf_counter() - start
    source = FileSource(path)
    logs = [Log.FromString(m.data) for m in source.robot_messages() if m.topic == Topic.EVENTS]
    texts = [log.message for log in logs]
    report = score(source)
    blocked = report.blocked
    return {
        "network": network,
        "seed": seed,
        "ended": result.status,
        "passable": kinds.count(ObstacleKind.PASSABLE),
        "blocking": kinds.count(ObstacleKind.BLOCKING),
        "stalls": sum(t.startswith("stall ") and t.endswith("into the pipe") for t in texts),
        "waits": sum("motors off" in t for t in texts),
        # Past a deposit, or on after the motors came back.
        "got_past": sum(
            t.startswith("stall: past it") or t.endswith("nothing ahead: driving on") for t in texts
        ),
        "gave_up": sum(blocked_visit(log) is not None for log in logs),
        "marks_right": len(blocked.true_positives) if blocked else 0,
        "marks_false": len(blocked.false_blocked) if blocked else 0,
        "missed": len(blocked.missed) if blocked else 0,
        "map": report.map_status,
        "sim_s": result.duration_ns / 1e9,
        "limit_s": default_time_limit_ns(net) / 1e9,
        "wall_s": wall,
    }


def _ablate(network: str, seed: int, args: argparse.Namespace) -> str:
    """One seed in the simulator alone, waiting for the motors and not."""
    from pipemap.sim import CameraSpec, World
    from pipemap.sim.controller import autonomous_run
    from pipemap.sim.recovery import RecoveryConfig

    net = build_network(network, seed=seed)
    settings = RecordSettings(
        network, seed=seed, obstacles=args.obstacles, motor_faults=args.motor_faults
    )
    cells = []
    for waits in (RecoveryConfig().motor_waits, 0):
        with World(net, seed=seed, obstacles=settings.deposits(net)) as world:
            result = autonomous_run(
                world,
                CameraSpec(resolution_px=32),
                seed,
                motor_faults=settings.cut_outs(net),
                recovery=RecoveryConfig(motor_waits=waits),
            )
        texts = [text for _, text in result.events]
        gave_up = sum(t.startswith("pipe blocked") for t in texts)
        waited = sum("motors off" in t for t in texts)
        cells.append(f"{result.status.value:<10} gave up {gave_up} waited {waited:>2}")
    return f"{network:<9} {seed:>4}  " + "   |   ".join(cells)


def main() -> None:
    """Run the benchmark and print one line per run, then the totals."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--obstacles", type=int, default=3)
    parser.add_argument("--motor-faults", type=int, default=0)
    parser.add_argument("--ablate-waits", action="store_true")
    parser.add_argument("--resolution", type=int, default=64)
    parser.add_argument("--networks", default="grid:2x3,random:8,paper,grid:3x3")
    parser.add_argument("--out", type=Path, default=None, help="keep the logs here")
    args = parser.parse_args()
    networks = args.networks.split(",")
    if args.ablate_waits:
        print(f"{'network':<9} {'seed':>4}  waiting for the motors (default)   |   not waiting")
        for seed in range(args.runs):
            print(_ablate(networks[seed % len(networks)], seed, args), flush=True)
        return
    header = (
        f"{'network':<9} {'seed':>4}  {'ended':<16} {'pass':>4} {'block':>5} {'stalls':>6} "
        f"{'waits':>5} {'past':>4} {'gave up':>7} {'right':>5} {'false':>5} {'missed':>6}  "
        f"{'map':<8} {'sim s':>6} {'limit':>6} {'wall s':>6}"
    )
    print(header)
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench-stuck-") as tmp:
        folder = args.out if args.out is not None else Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        for seed in range(args.runs):
            r = _run(networks[seed % len(networks)], seed, args, folder)
            rows.append(r)
            print(
                f"{r['network']:<9} {r['seed']:>4}  {r['ended']:<16} {r['passable']:>4} "
                f"{r['blocking']:>5} {r['stalls']:>6} {r['waits']:>5} {r['got_past']:>4} "
                f"{r['gave_up']:>7} "
                f"{r['marks_right']:>5} {r['marks_false']:>5} {r['missed']:>6}  {r['map']:<8} "
                f"{r['sim_s']:>6.0f} {r['limit_s']:>6.0f} {r['wall_s']:>6.1f}",
                flush=True,
            )
    met = [r for r in rows if r["stalls"]]
    print(
        f"\n{len(rows)} runs, {sum(r['passable'] for r in rows)} passable and "
        f"{sum(r['blocking'] for r in rows)} blocking deposits; {len(met)} runs stalled, "
        f"{sum(r['stalls'] for r in rows)} stalls ({sum(r['waits'] for r in rows)} waits for "
        f"the motors): got past {sum(r['got_past'] for r in rows)}, "
        f"gave up {sum(r['gave_up'] for r in rows)} pipes "
        f"({sum(r['marks_right'] for r in rows)} marks truly blocked, "
        f"{sum(r['marks_false'] for r in rows)} false, {sum(r['missed'] for r in rows)} "
        "blocked pipes missed)"
    )
    ended: dict[str, int] = {}
    for r in rows:
        ended[r["ended"]] = ended.get(r["ended"], 0) + 1
    hung = sum(r["sim_s"] >= r["limit_s"] for r in rows)
    maps: dict[str, int] = {}
    for r in rows:
        maps[r["map"]] = maps.get(r["map"], 0) + 1
    print(f"ended: {ended}; map: {maps}; at the time limit (a hang): {hung}")


if __name__ == "__main__":
    main()
