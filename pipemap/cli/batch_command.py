"""``pipemap batch SPEC.toml --out DIR`` and ``pipemap batch-report DIR``.

Everything is checked before the first run: the SPEC (one line per mistake), the
output folder, the cluster's address. Then the runs go to Ray; each finished run is
shown as a line (or, on a terminal, as one progress line kept up to date), and
Ctrl-C stops the batch keeping every finished run (exit 130). Exit status 1 when a
run failed (after its retry), 0 otherwise.
"""

from __future__ import annotations

import argparse
import signal
import sys
from pathlib import Path
from typing import Any, TextIO

from pipemap.cli.outputs import output_folder

__all__ = ["format_duration", "progress_printer", "run_batch_command", "run_batch_report"]


def format_duration(seconds: float) -> str:
    """``42 s``, ``3 min 05 s``, ``1 h 02 min``."""
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def _verdict(doc: Any) -> str:
    if doc["status"] != "ok":
        return f"FAILED: {doc['reason']}"
    score = doc["score"]
    d = score["decisions"]
    right = d["correct_known"] + d["correct_new"]
    map_ = "map correct" if score["map_correct"] else "map WRONG"
    return f"{map_}, {right}/{score['visits']} decisions right"


def progress_printer(err: TextIO) -> Any:
    """The batch's progress: one line kept up to date on a terminal, else one line
    per finished run."""
    tty = err.isatty()
    width = [0]

    def show(e: Any) -> None:
        if e.kind == "start":
            if not tty:
                return
        elif not tty:
            if e.kind in ("ok", "failed"):
                err.write(
                    f"[{e.done:{len(str(e.total))}d}/{e.total}] {e.point.run_id}: "
                    f"{_verdict(e.doc)}\n"
                )
                err.flush()
            return
        eta = "estimating time left" if e.eta_s is None else f"{format_duration(e.eta_s)} left"
        line = (
            f"batch: {e.done}/{e.total} runs done, {e.failed} failed, {e.running} running, "
            f"{format_duration(e.elapsed_s)} elapsed, {eta}"
        )
        err.write("\r" + line.ljust(width[0]))
        width[0] = len(line)
        if e.kind == "failed":
            err.write(f"\n  {e.point.run_id}: {_verdict(e.doc)}\n")
            width[0] = 0
        err.flush()

    return show


def _describe(plan: Any, address: str | None) -> str:
    spec = plan.spec
    where = "a Ray cluster at " + address if address else "Ray on this machine"
    skipped = f"; {len(plan.complete)} complete runs kept, skipped" if plan.complete else ""
    return (
        f"batch {spec.name}: {len(plan.pending)} runs to make ({spec.recordings()} "
        f"recordings in all) on {where}{skipped}\n"
    )


def run_batch_command(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Validate the SPEC, the folder and the address; run; print the summary."""
    from pipemap.batch import BatchOptions, load_spec, plan_batch, run_batch

    spec = load_spec(Path(args.spec))
    options = BatchOptions(
        address=args.address,
        workers=args.workers,
        keep_logs=args.keep_logs,
        resume=args.resume,
        force=args.force,
    )
    # Writable before any work (the batch's own check then decides --resume/--force).
    output_folder(args.out, "--out", force=True)
    plan = plan_batch(spec, Path(args.out), options)
    err.write(_describe(plan, args.address))
    err.flush()
    summary = run_batch(plan, progress_printer(err))
    if err.isatty():
        err.write("\n")
    made = summary.done - summary.failed
    line = (
        f"batch {spec.name}: {made} runs made, {summary.failed} failed, {summary.skipped} "
        f"kept from before, of {summary.total}; {summary.workers} workers, "
        f"{format_duration(summary.wall_s)}; results in {plan.out / 'results.csv'}\n"
    )
    if summary.interrupted:
        name = signal.Signals(summary.stop_signal or signal.SIGINT).name
        err.write(
            f"pipemap: interrupted ({name}): {summary.done} finished runs kept in "
            f"{plan.out}; --resume makes the rest\n"
        )
        out.write(line)
        return 128 + (summary.stop_signal or signal.SIGINT)
    out.write(line)
    return 1 if summary.failed else 0


def run_batch_report(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Write the grouped tables and figures of a batch folder."""
    from pipemap.batch import write_report

    folder = Path(args.dir)
    by = None if args.by is None else tuple(k.strip() for k in args.by.split(",") if k.strip())
    written = write_report(folder, by)
    out.write(f"batch-report: {', '.join(str(p) for p in written)}\n")
    return 0
