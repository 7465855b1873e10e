"""``pipemap import`` and ``pipemap export``: ROS 2 bags in and out of pipemap.

Each checks its output paths before reading anything, then calls :mod:`pipemap.api`;
what an import could not use is said on standard error, a note a line."""

from __future__ import annotations

import argparse
import sys
from typing import TextIO

__all__ = ["run_import"]


def run_import(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Check the output, read the bag, write the log, print a summary and the notes."""
    from pipemap import api
    from pipemap.cli.outputs import output_file
    from pipemap.recorder.ros2_contract import load_spec

    target = output_file(args.output, "-o", args.force)
    assert target is not None  # -o is required
    spec = load_spec(args.spec)
    result = api.import_bag(args.bag, target, spec, overwrite=True)
    for note in result.notes:
        err.write(f"pipemap: note: {note}\n")
    images = result.counts.get("/robot/camera/image", 0)
    out.write(
        f"{args.bag}: {result.sweeps} sweeps ({images} images) in {result.visits} visits "
        f"-> {target}\n"
    )
    return 0
