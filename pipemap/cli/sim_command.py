"""``pipemap sim``: run an episode and save every sweep in the paper's folder layout.

The episode is the one ``pipemap record`` runs, with the localizer online, through
:func:`pipemap.api.simulate`: no log is written, and each visit's sweep goes to
``DIR/0001``, ``DIR/0002``, ... (see :mod:`pipemap.sweep_folders`), so that
``pipemap map DIR/*`` maps the run. In the ``active`` condition the probe sweeps go
to ``DIR/NNNN/probes/<kind>/``.
"""

from __future__ import annotations

import argparse
import sys
from typing import TextIO

from pipemap.cli.outputs import output_folder
from pipemap.cli.run_settings import check_condition_flags, explore_policy, record_settings

__all__ = ["run_sim"]


def run_sim(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Validate, run the episode through :func:`pipemap.api.simulate`, print a summary."""
    from pipemap import api
    from pipemap.cli.log_commands import progress_printer

    check_condition_flags(args)
    target = output_folder(args.save_sweeps, "--save-sweeps", args.force)
    settings = record_settings(args)
    progress = progress_printer(err, "simulating")
    result = api.simulate(target, settings, args.force, progress)
    if err.isatty():
        err.write("\n")
    condition = args.condition
    if condition == "autonomous":
        condition += f", explore {explore_policy(args)}"
    status = result.status
    if result.status == "finished" and not result.ok:
        status = "stopped early: not every node and pipe was visited"
    conditions = [f"{args.obstacles} deposits"] if args.obstacles else []
    conditions += [f"{args.motor_faults} motor cut-outs"] if args.motor_faults else []
    out.write(
        f"network {args.network}, condition {condition}: {result.visits} visits of "
        f"{len(result.true_nodes)}/{result.node_count} nodes "
        f"({result.pipes_driven}/{result.pipe_count} pipes), {result.sweeps} sweeps, "
        f"{result.distance_m:.2f} m in {result.duration_ns / 1e9:.0f} s simulated, {status}"
        + (
            f"; {', '.join(conditions)}: got past {result.stalls_recovered} stall(s), gave up "
            f"{result.pipes_given_up} pipe(s) as blocked"
            if conditions
            else ""
        )
        + "\n"
    )
    return 0 if result.ok else 1
