"""What drawing the world's textures at the camera's scale would save, and what it would
change: one record with the 512-row textures ``pipemap record`` draws, and one with
textures sized to the camera.

    python benchmarks/bench_texture_size.py [--network paper] [--resolution 32 96 400]
                                            [--repeat N]

``pipemap record`` draws every pipe's texture with 512 rows around the circumference
(``sim.world.World``'s ``texture_px``), whatever the camera's resolution: about 1.2 mm a
texel, one pixel of the default 400 px camera on a wall 0.3 m away. A smaller camera's
pixel covers a larger patch of wall, and TinyRenderer takes one texture sample a pixel. The
sized way keeps the default camera's texels per pixel: the smallest power of two of rows
at or above ``512 * resolution / 400``, 64..512 (:func:`sized_rows`: 64 at 32 px, 128
at 64 and 96 px, 512 above 200 px).

For each resolution, records the autonomous run of ``--network`` from its default start
both ways, each in a fresh Python process, N times each, the two ways taking turns.
Prints the least CPU seconds (user + system, the process and its children: the log
writer) and wall seconds of each way, the run's sweeps and outcome, and the SHA-256 of
each log (the same bytes both ways above 200 px).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

#: Rows of a pipe's texture that ``pipemap record`` draws, whatever the camera.
RECORD_ROWS = 512


def sized_rows(resolution_px: int) -> int:
    """Rows of texture that keep the default camera's texels per pixel, 64..512."""
    needed = RECORD_ROWS * resolution_px / 400
    rows = 64
    while rows < needed and rows < RECORD_ROWS:
        rows *= 2
    return rows


def _child(network_name: str, resolution: int, fixed: bool, out: Path) -> None:
    """One record in this process; prints its figures as one line of JSON."""
    from functools import partial

    from pipemap import __version__
    from pipemap.recorder import RecordSettings, record_run, session
    from pipemap.sim.network import build_network

    size = RECORD_ROWS if fixed else sized_rows(resolution)
    session.World = partial(session.World, texture_px=size)  # type: ignore[attr-defined]
    network = build_network(network_name, seed=0)
    settings = RecordSettings(network_name, resolution_px=resolution)
    start = time.perf_counter()
    result = record_run(out, settings, network, __version__)
    wall = time.perf_counter() - start
    own = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
    digest = hashlib.sha256(out.read_bytes()).hexdigest()
    print(
        json.dumps(
            {
                "texture_px": size,
                "cpu_s": cpu,
                "wall_s": wall,
                "sha256": digest,
                "sweeps": result.sweeps,
                "status": result.status,
            }
        )
    )


def _run(network: str, resolution: int, fixed: bool, folder: Path) -> dict[str, object]:
    how = "fixed" if fixed else "sized"
    out = folder / f"{network.replace(':', '_')}-{resolution}-{how}.mcap"
    argv = [sys.executable, __file__, "--child", network, str(resolution), str(int(fixed))]
    argv.append(str(out))
    done = subprocess.run(argv, capture_output=True, text=True, check=True)
    out.unlink()
    return dict(json.loads(done.stdout.strip().splitlines()[-1]))


def main() -> int:
    if len(sys.argv) == 6 and sys.argv[1] == "--child":
        _child(sys.argv[2], int(sys.argv[3]), sys.argv[4] == "1", Path(sys.argv[5]))
        return 0
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--network", default="paper")
    parser.add_argument("--resolution", type=int, nargs="+", default=[32, 96, 400])
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    print(f"{args.network}, autonomous record, each in a fresh process, best of {args.repeat}:")
    print("  px  textures      CPU s   wall s  sweeps  status             log sha256")
    with tempfile.TemporaryDirectory() as tmp:
        for resolution in args.resolution:
            tries: list[list[dict[str, object]]] = [[], []]
            for _ in range(args.repeat):
                for way, fixed in enumerate((True, False)):
                    tries[way].append(_run(args.network, resolution, fixed, Path(tmp)))
            rows = [min(way, key=lambda row: float(row["cpu_s"])) for way in tries]  # type: ignore[arg-type]
            for way in tries:  # the same log bytes every time
                assert len({row["sha256"] for row in way}) == 1
            for row, how in zip(rows, ("512 rows", "sized"), strict=True):
                print(
                    f"{resolution:4d}  {how:8s} {row['texture_px']:4d}"
                    f" {row['cpu_s']:7.1f} {row['wall_s']:8.1f} {row['sweeps']:7d}"
                    f"  {str(row['status']):18s} {str(row['sha256'])[:16]}"
                )
            same = rows[0]["sha256"] == rows[1]["sha256"]
            saved = 1.0 - float(rows[1]["cpu_s"]) / float(rows[0]["cpu_s"])  # type: ignore[arg-type]
            print(f"      same log bytes: {'yes' if same else 'no'}; CPU saved {100 * saved:.0f} %")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
