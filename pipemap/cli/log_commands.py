"""``pipemap record`` and ``pipemap info``: write a run's log, and describe one.

``record`` validates everything before it creates the file, refuses to overwrite
without ``--force``, and on Ctrl-C (or SIGTERM) closes the log properly with what
was recorded so far and exits 130 saying so. ``info`` reads a log whole, or up to
where it was cut or damaged, and says which.
"""

from __future__ import annotations

import argparse
import json
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any, TextIO

from pipemap import __version__
from pipemap.errors import InputError

__all__ = ["run_info", "run_record"]


def _interrupt_once() -> Callable[[], None]:
    """Turn the first SIGINT or SIGTERM into KeyboardInterrupt and ignore the rest, so
    that a second Ctrl-C cannot break the closing of the log. Returns a restorer."""
    previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}

    def handler(signum: int, frame: FrameType | None) -> None:
        for s in previous:
            signal.signal(s, signal.SIG_IGN)
        raise KeyboardInterrupt

    for s in previous:
        signal.signal(s, handler)

    def restore() -> None:
        for s, h in previous.items():
            signal.signal(s, h)

    return restore


def _progress_printer(err: TextIO) -> Callable[[Any], None] | None:
    if not err.isatty():
        return None

    def show(p: Any) -> None:
        err.write(
            f"\rrecording: {p.sim_time_ns / 1e9:7.1f} s simulated, {p.sweeps} sweeps, "
            f"{p.visits} node visits "
        )
        err.flush()

    return show


def run_record(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Validate, run the episode while writing its log, print a summary."""
    from pipemap.recorder import RecordSettings, record_run
    from pipemap.sim.episode import Condition
    from pipemap.sim.network import build_network

    target = Path(args.output)
    if target.is_dir():
        raise InputError(f"-o {target}: is a folder, not a file")
    if target.exists() and not args.force:
        raise InputError(f"-o {target}: exists; refusing to overwrite without --force")
    if not target.parent.is_dir():
        raise InputError(f"-o {target}: folder {target.parent} does not exist")
    network = build_network(args.network, seed=args.seed)
    if args.start is not None and args.start not in network.labels:
        raise InputError(
            f"--start {args.start}: no such node in {args.network} ({', '.join(network.labels)})"
        )
    if args.save and not args.view:
        raise InputError("--save: writes the view of the run, so it needs --view")
    view_target = None
    if args.view:
        from pipemap.cli.view_command import check_view_target

        view_target = check_view_target(target, args.save, args.force)
    from pipemap.recorder.online import Explore

    settings = RecordSettings(
        network=args.network,
        start=args.start,
        seed=args.seed,
        condition=Condition(args.condition),
        resolution_px=args.resolution,
        images_per_sweep=args.images,
        align_sweeps=args.align_sweeps,
        threshold=args.threshold,
        explore=Explore(args.explore),
    )
    progress = _progress_printer(err)
    restore = _interrupt_once()
    try:
        result = record_run(target, settings, network, __version__, progress, args.force)
    except KeyboardInterrupt:
        if progress is not None:
            err.write("\n")
        err.write(f"pipemap: interrupted: {target} closed with everything recorded so far\n")
        return 130
    finally:
        restore()
    if progress is not None:
        err.write("\n")
    size_mb = target.stat().st_size / 1e6
    condition = args.condition
    if condition == "autonomous":
        condition += f" (explore {args.explore})"
    status = result.status
    if result.status == "finished" and not result.ok:
        status = "finished, but not every node and pipe was visited"
    out.write(
        f"recorded {target} ({size_mb:.1f} MB, {result.messages} messages): network "
        f"{args.network}, condition {condition}, {result.sweeps} sweeps, "
        f"{result.visits} visits of {len(result.true_nodes)}/{result.node_count} nodes "
        f"({result.pipes_driven}/{result.pipe_count} pipes), "
        f"{result.distance_m:.2f} m in {result.duration_ns / 1e9:.0f} s simulated, "
        f"{status}\n"
    )
    if args.view:
        from pipemap.cli.view_command import view_recorded

        view_recorded(target, view_target, args.threshold, out, err)
    return 0 if result.ok else 1


def info_document(path: Path) -> dict[str, Any]:
    """What ``pipemap info --json`` prints."""
    from pipemap.recorder import METADATA_RESULT, METADATA_RUN, Topic, read_log
    from pipemap.recorder.schemas import NodeEvent, SweepCommand

    contents = read_log(path, keep=lambda topic: topic in (Topic.SWEEP, Topic.NODE))
    sweeps = visits = 0
    for m in contents.messages:
        if m.topic == Topic.SWEEP:
            sweeps += SweepCommand.FromString(m.data).phase == SweepCommand.START
        else:
            visits += NodeEvent.FromString(m.data).kind == NodeEvent.ARRIVAL
    metadata: dict[str, Any] = dict(contents.metadata.get(METADATA_RUN, {}))
    metadata["result"] = contents.metadata.get(METADATA_RESULT)
    return {
        "file": str(path),
        "writer": contents.library,
        "duration_s": contents.duration_ns / 1e9,
        "messages": sum(contents.counts.values()),
        "integrity": contents.integrity.value,
        "problem": contents.problem or None,
        "channels": [
            {"topic": c.topic, "schema": c.schema_name, "count": contents.counts.get(c.topic, 0)}
            for c in sorted(contents.channels.values(), key=lambda c: c.channel_id)
        ],
        "sweeps": sweeps,
        "visits": visits,
        "metadata": metadata,
    }


def run_info(args: argparse.Namespace, out: TextIO) -> int:
    """Describe a log; exit 0 if it is whole or cut short, 1 if it is damaged."""
    doc = info_document(Path(args.log))
    if args.json:
        out.write(json.dumps(doc, indent=2) + "\n")
    else:
        meta = doc["metadata"]
        result = meta.get("result") or {}
        integrity = doc["integrity"] + (f" ({doc['problem']})" if doc["problem"] else "")
        lines = [
            f"file       {doc['file']}",
            f"integrity  {integrity}",
            f"duration   {doc['duration_s']:.3f} s simulated",
            f"messages   {doc['messages']}",
            f"run        network {meta.get('network', '?')}, start {meta.get('start', '?')}, "
            f"seed {meta.get('seed', '?')}, condition {meta.get('condition', '?')}, "
            f"explore {meta.get('explore', 'right-hand')}, "
            f"{meta.get('resolution_px', '?')} px, {meta.get('images_per_sweep', '?')} images",
            f"sweeps     {doc['sweeps']} in {doc['visits']} node visits",
            f"result     {result.get('status', 'none recorded')}",
            f"written by {doc['writer']}, log format {meta.get('format_version', '?')}",
            "channels",
        ]
        width = max(len(c["topic"]) for c in doc["channels"]) if doc["channels"] else 0
        schema_width = max((len(c["schema"]) for c in doc["channels"]), default=0)
        for c in doc["channels"]:
            lines.append(f"  {c['topic']:<{width}}  {c['schema']:<{schema_width}}  {c['count']:>8}")
        out.write("\n".join(lines) + "\n")
    return 1 if doc["integrity"] == "corrupt" else 0
