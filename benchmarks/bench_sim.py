"""Benchmark of the simulator: world build, render time per image, a full paper tour.

Prints, pinned to one core: the time to build the ``paper`` world (meshes, textures,
collision), the render time per image at 400x400 and 800x800 (TinyRenderer plus
lighting; median of 12 views from the junction centres), and the wall time of a
complete ``paper`` tour in the ``perfect`` condition at 400x400 (13 sweeps of 6
images), and a full autonomous ``paper`` exploration at 400x400 from S with its
real-time factor (simulated seconds per wall second).

Usage: ``python benchmarks/bench_sim.py``.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402

cv2.setNumThreads(1)
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from pipemap.sim import CameraSpec, Condition, Episode, SimConfig, World, build_network  # noqa: E402
from pipemap.sim.controller import autonomous_run  # noqa: E402


def main() -> int:
    network = build_network("paper")
    start = time.perf_counter()
    world = World(network, seed=0)
    build = time.perf_counter() - start
    print(f"# paper network: {len(network.nodes)} nodes, {len(network.pipes)} pipes, one core")
    triangles = world.triangle_count
    print(f"world build (meshes, textures, collision): {build:.2f} s, {triangles} triangles")
    for resolution in (400, 800):
        camera = CameraSpec(resolution_px=resolution)
        times = []
        for label in "ABCD":
            node = network.node(label)
            for j in range(3):
                t0 = time.perf_counter()
                world.render((node.x_m + 1e-4, node.y_m + 1e-4, 0.05), j * math.pi / 3, camera)
                times.append(time.perf_counter() - t0)
        median_ms = statistics.median(times) * 1000
        print(f"render per image at {resolution}x{resolution}: {median_ms:.0f} ms")
    t0 = time.perf_counter()
    visits = list(Episode(world, SimConfig(Condition.PERFECT)).visits())
    tour = time.perf_counter() - t0
    print(
        f"paper tour, perfect condition, 400x400: {len(visits)} sweeps in {tour:.1f} s "
        f"({tour / (6 * len(visits)) * 1000:.0f} ms per image)"
    )
    t0 = time.perf_counter()
    result = autonomous_run(world, CameraSpec(resolution_px=400), seed=0)
    wall = time.perf_counter() - t0
    simulated = result.duration_ns / 1e9
    print(
        f"paper autonomous exploration, 400x400: {result.status.value}, {len(result.sweeps)} "
        f"sweeps, {result.distance_m:.1f} m, {simulated:.0f} s simulated in {wall:.1f} s wall: "
        f"{simulated / wall:.0f}x real time"
    )
    world.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
