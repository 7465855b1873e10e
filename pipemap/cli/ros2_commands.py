"""``pipemap import`` and ``pipemap export``: ROS 2 bags in and out of pipemap.

Each checks its output paths before reading anything, then calls :mod:`pipemap.api`;
what an import could not use is said on standard error, a note a line."""

from __future__ import annotations

import argparse
import sys
from typing import TextIO

__all__ = ["run_export", "run_import"]


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


def run_export(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Check every output and the log, then write each export asked for."""
    from pathlib import Path

    from pipemap import api
    from pipemap.cli.outputs import output_file, output_folder
    from pipemap.errors import InputError
    from pipemap.recorder.trajectory import ESTIMATED, JUNCTIONS, TRUTH

    if args.ros2 is None and args.tum is None and args.geojson is None:
        raise InputError("export: say what to write: --ros2 OUT, --tum DIR or --geojson OUT")
    geojson = output_file(args.geojson, "--geojson", args.force)
    ros2 = None if args.ros2 is None else output_folder(args.ros2, "--ros2", args.force)
    if ros2 is not None:
        api.ros2_available()
    tum = None
    if args.tum is not None:
        mine = (ESTIMATED, TRUTH, JUNCTIONS)
        tum = output_folder(
            args.tum,
            "--tum",
            args.force,
            lambda f: sorted(p.name for p in f.iterdir() if p.name in mine),
        )
    if Path(args.log).suffix == ".json":  # a map document: GeoJSON is all it gives
        if ros2 is not None or tum is not None or geojson is None:
            raise InputError(
                f"{args.log}: a map document gives --geojson only; --ros2 and "
                "--tum need the run's log"
            )
        features = api.export_geojson(Path(args.log), geojson)
        out.write(f"{geojson}: {features} features (junctions and pipes)\n")
        return 0
    log = api.open_log(args.log)  # a missing or foreign file is refused before any writing
    if ros2 is not None:
        result = api.export_ros2(log.path, ros2, overwrite=True)
        total = sum(result.counts.values())
        out.write(f"{ros2}: {total} messages on {len(result.counts)} topics\n")
        if result.undecodable:
            err.write(
                f"pipemap: warning: {result.undecodable} message(s) do not decode; left out\n"
            )
    if tum is not None:
        written = api.export_tum(Path(args.log), tum)
        counts = written.counts
        out.write(
            f"{tum}: {counts[ESTIMATED]} dead-reckoned poses, {counts[TRUTH]} true poses, "
            f"{counts[JUNCTIONS]} junctions\n"
        )
        if not counts[TRUTH]:
            err.write(f"pipemap: note: {args.log}: no ground truth (/truth/pose): no {TRUTH}\n")
    if geojson is not None:
        features = api.export_geojson(Path(args.log), geojson)
        out.write(f"{geojson}: {features} features (junctions and pipes)\n")
    return 0
