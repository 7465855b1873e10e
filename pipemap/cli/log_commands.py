"""``pipemap record`` and ``pipemap info``: write a run's log, and describe one.

``record`` validates everything before it creates the file, refuses to overwrite
without ``--force``, and on Ctrl-C (or SIGTERM, SIGHUP) closes the log properly with
what was recorded so far and exits 130 (143, 129) saying so. ``info`` reads a log whole, or up to
where it was cut or damaged, and says which.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TextIO

from pipemap import __version__
from pipemap.cli.exits import stop_signals, stopped_status
from pipemap.cli.run_settings import check_condition_flags, explore_policy, record_settings
from pipemap.errors import InputError, ViewerError

__all__ = ["progress_printer", "run_info", "run_record"]


#: A world that takes longer than this to build says how far it has come.
_QUIET_BUILD_S = 2.0


def progress_printer(err: TextIO, doing: str = "recording") -> Callable[[Any], None] | None:
    """On a terminal, a line that says how far a run has come (``doing``: what it
    does), and how far a world that is slow to build has been built."""
    if not err.isatty():
        return None
    started: list[float] = []

    def show(p: Any) -> None:
        if p.world_pieces is not None:
            built, pieces = p.world_pieces
            started[:] = started or [time.monotonic()]
            if time.monotonic() - started[0] >= _QUIET_BUILD_S:
                err.write(f"\rbuilding the world: {built}/{pieces} pipes and nodes ")
                err.flush()
            return
        err.write(
            f"\r{doing}: {p.sim_time_ns / 1e9:7.1f} s simulated, {p.sweeps} sweeps, "
            f"{p.visits} node visits "
        )
        err.flush()

    return show


def _close_live(live: Any, err: TextIO) -> Any:
    """End the live view, if any: what it showed, or ``None`` if it had stopped (said
    in a note: the log is written all the same)."""
    if live is None:
        return None
    try:
        return live.close()
    except ViewerError as exc:
        err.write(f"pipemap: note: {exc}\n")
        return None


def _conditions_note(simulator: Any) -> str:
    """``, N obstacles`` when the run's simulator settings put deposits in pipes, and
    ``, N motor cut-outs`` when they cut the motors out."""
    if not isinstance(simulator, dict):
        return ""
    note = ""
    for key, noun in (("obstacles", "obstacles"), ("motor_faults", "motor cut-outs")):
        settings = simulator.get(key)
        count = settings.get("count") if isinstance(settings, dict) else None
        note += f", {count} {noun}" if isinstance(count, int) and count > 0 else ""
    return note


def _run_line(meta: dict[str, Any]) -> str:
    """The ``run`` line of ``info``: the run's settings, or that they are lost."""
    if "format_version" not in meta:
        return "run        lost: its pipemap.run record is damaged; the settings are not known"
    return (
        f"run        network {meta.get('network', '?')}, start {meta.get('start', '?')}, "
        f"seed {meta.get('seed', '?')}, condition {meta.get('condition', '?')}, "
        f"explore {meta.get('explore', 'right-hand')}, "
        f"{meta.get('resolution_px', '?')} px, {meta.get('images_per_sweep', '?')} images"
        + _conditions_note(meta.get("simulator"))
    )


def run_record(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Validate, run the episode while writing its log, print a summary."""
    from pipemap import api
    from pipemap.cli.outputs import output_file
    from pipemap.sim.network import build_network
    from pipemap.sim.world_budget import check_world_fits

    check_condition_flags(args)
    if args.no_probe_moves and args.condition != "autonomous":
        raise InputError(
            f"--no-probe-moves: only the autonomous robot makes its own probe moves "
            f"(condition {args.condition})"
        )
    target = output_file(args.output, "-o", args.force)
    assert target is not None  # -o is required
    network = build_network(args.network, seed=args.seed)
    check_world_fits(network, args.network, args.world_memory)
    if args.start is not None and args.start not in network.labels:
        raise InputError(
            f"--start {args.start}: no such node in {args.network} ({', '.join(network.labels)})"
        )
    if args.jpeg_quality is not None and args.image_format != "jpeg":
        raise InputError("--jpeg-quality: sets the JPEG encoding, so it needs --image-format jpeg")
    if args.save and not args.view:
        raise InputError("--save: writes the view of the run, so it needs --view")
    if args.connect is not None and not args.view:
        raise InputError("--connect: streams the run to a viewer, so it needs --view")
    view_target = None
    if args.view:
        from pipemap.cli.view_command import check_view_target

        view_target = check_view_target(target, args.save, args.force, args.connect)
    settings = record_settings(args)
    settings.deposits(network)  # too many for the network: an error before any work
    live = None
    if args.view and not args.save:
        from pipemap.cli.view_command import live_view

        live = live_view(settings.metadata(network, __version__), args.threshold, args.connect)
    progress = progress_printer(err)
    try:
        with stop_signals():
            result = api.record(target, settings, args.force, progress, live)
    except KeyboardInterrupt as exc:
        if err.isatty():
            err.write("\n")
        status, name = stopped_status(exc)
        err.write(
            f"pipemap: interrupted ({name}): {target} closed with everything recorded so far\n"
        )
        return status
    finally:
        shown = _close_live(live, err)
    if err.isatty():
        err.write("\n")
    size_mb = target.stat().st_size / 1e6
    condition = args.condition
    if condition == "autonomous":
        condition += f" (explore {explore_policy(args)})"
    outcome = result.status
    if result.status == "finished" and not result.ok:
        outcome = "finished, but not every node and pipe was visited"
    out.write(
        f"recorded {target} ({size_mb:.1f} MB, {result.messages} messages): network "
        f"{args.network}, condition {condition}, {result.sweeps} sweeps, "
        f"{result.visits} visits of {len(result.true_nodes)}/{result.node_count} nodes "
        f"({result.pipes_driven}/{result.pipe_count} pipes), "
        f"{result.distance_m:.2f} m in {result.duration_ns / 1e9:.0f} s simulated, "
        f"{outcome}\n"
    )
    if live is not None:
        if shown is not None:
            from pipemap.cli.view_command import live_summary

            out.write(live_summary(str(target), shown, args.connect) + "\n")
    elif args.view:
        from pipemap.cli.view_command import view_recorded

        view_recorded(target, view_target, args.threshold, out, err)
    return 0 if result.ok else 1


def run_info(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Describe a log; exit 0 if it is whole or cut short, 1 if it is damaged."""
    from pipemap import api

    doc = api.log_info(Path(args.log))
    if args.json:
        out.write(json.dumps(doc, indent=2) + "\n")
    else:
        meta = doc["metadata"]
        result = meta.get("result") or {}
        lines = [f"file       {doc['file']}", f"integrity  {doc['integrity']}"]
        for d in doc["damage"]:
            lines.append(f"  damaged  {d['text']}")
        if doc["truncated"]:
            lines.append(f"  cut      {doc['truncated']}")
        for topic, count in sorted(doc["undecodable"].items()):
            lines.append(f"  unreadable {count} message(s) on {topic} do not decode")
        skipped = doc["sweeps_skipped"]
        lines += [
            f"duration   {doc['duration_s']:.3f} s simulated",
            f"messages   {doc['messages']}",
            _run_line(meta),
            f"sweeps     {doc['sweeps']} complete in {doc['visits']} node visits"
            + (f" ({len(skipped)} skipped by a replay)" if skipped else ""),
            f"result     {result.get('status', 'none recorded')}",
            f"written by {doc['writer']}, log format {meta.get('format_version', '?')}",
            "channels",
        ]
        width = max(len(c["topic"]) for c in doc["channels"]) if doc["channels"] else 0
        schema_width = max((len(c["schema"]) for c in doc["channels"]), default=0)
        for c in doc["channels"]:
            lines.append(f"  {c['topic']:<{width}}  {c['schema']:<{schema_width}}  {c['count']:>8}")
        lines += [f"  skipped  {line}" for line in skipped]
        out.write("\n".join(lines) + "\n")
    return 1 if doc["integrity"] == "corrupt" else 0
