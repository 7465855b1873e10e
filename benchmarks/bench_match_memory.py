"""Peak memory of ``pipemap match`` on a pair of image sets, up to the largest size it
reads (4096 px a side, ``pipemap.pngcheck.MAX_IMAGE_SIDE_PX``).

Two sets of six square RGB JPEGs are made at each ``--sizes`` (smooth random texture,
the second set the first turned by two images, so the pair matches as a revisit
does), then ``PYTHON -m pipemap match --json A B`` runs as a user runs it, under GNU
time (``/usr/bin/time``): its peak resident memory, CPU (user + system) and wall
time. The bound it is compared with is what the images themselves take decoded: two
sets of six images of WxW gray pixels (``2 * 6 * W * W`` bytes); ``x_images`` is the
peak over that.

Usage: ``python benchmarks/bench_match_memory.py [--sizes 800 4096]``; prints one JSON
document.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

#: GNU time: CPU and peak memory of the command alone.
TIME = "/usr/bin/time"
IMAGES = 6


def make_sets(root: Path, side: int) -> tuple[Path, Path]:
    """Two sets of ``IMAGES`` JPEGs of ``side`` px: the second is the first turned by
    two images (a junction seen again from another heading)."""
    rng = np.random.default_rng(side)
    small = rng.integers(0, 256, (IMAGES, 48, 48, 3), dtype=np.uint8)
    images = [cv2.resize(im, (side, side), interpolation=cv2.INTER_CUBIC) for im in small]
    folders = []
    for name, order in (("a", range(IMAGES)), ("b", [(i + 2) % IMAGES for i in range(IMAGES)])):
        folder = root / f"{side}_{name}"
        folder.mkdir()
        for k, i in enumerate(order, start=1):
            cv2.imwrite(str(folder / f"camera_image{k}.jpeg"), images[i])
        folders.append(folder)
    return folders[0], folders[1]


def measure(python: str, a: Path, b: Path, side: int) -> dict[str, object]:
    """``pipemap match --json A B`` under GNU time."""
    with tempfile.NamedTemporaryFile("r", suffix=".time") as report:
        started = time.perf_counter()
        done = subprocess.run(
            [TIME, "-f", "%U %S %M", "-o", report.name, python, "-m", "pipemap", "match"]
            + ["--json", str(a), str(b)],
            capture_output=True,
            text=True,
            timeout=3600,
        )
        wall = time.perf_counter() - started
        user, system, peak_kib = report.read().split()[-3:]
    if done.returncode != 0:
        raise SystemExit(f"pipemap match at {side} px: exit {done.returncode}: {done.stderr}")
    peak = int(peak_kib) * 1024
    images = 2 * IMAGES * side * side
    return {
        "side_px": side,
        "exit": done.returncode,
        "peak_mib": round(peak / 2**20, 1),
        "images_gray_mib": round(images / 2**20, 1),
        "x_images": round(peak / images, 2),
        "cpu_s": round(float(user) + float(system), 2),
        "wall_s": round(wall, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[800, 4096])
    parser.add_argument("--python", default=sys.executable)
    args = parser.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for side in args.sizes:
            a, b = make_sets(Path(tmp), side)
            rows.append(measure(args.python, a, b, side))
    print(json.dumps({"python": args.python, "sets": 2, "images": IMAGES, "runs": rows}, indent=2))


if __name__ == "__main__":
    main()
