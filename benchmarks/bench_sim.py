"""Benchmark of the simulator: world build, render time per image, a full paper tour.

Prints, pinned to one core: the time to build the ``paper`` world (meshes, textures,
collision), the render time per image at 400x400 and 800x800 (TinyRenderer plus
lighting; median of 12 views from the junction centres), and the wall time of a
complete ``paper`` tour in the ``perfect`` condition at 400x400 (13 sweeps of 6
images), and a full autonomous ``paper`` exploration at 400x400 from S with its
real-time factor (simulated seconds per wall second).

Usage: ``python benchmarks/bench_sim.py [--network NAME] [--resolution PX] [--no-run]``.
With ``--network`` (``grid:10x10``, ``random:100``, ...) it measures that network
instead: world build time and the memory it adds (resident set), render time per
image at the first 12 nodes' centres with culling on, the pieces those images built
and the memory then (the world is streamed: ``sim/world.py``); with ``--whole`` the
world is built whole first and the views are drawn with culling off too (see
``sim/visibility.py``; the images are compared); and (unless ``--no-run``) an autonomous run
at ``--resolution`` with its real-time factor. CPU time (``time.process_time``) is
printed beside wall time.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import math  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402

cv2.setNumThreads(1)
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from resident import rss_mib as _rss_mib  # noqa: E402

from pipemap.sim import CameraSpec, Condition, Episode, SimConfig, World, build_network  # noqa: E402
from pipemap.sim.controller import autonomous_run  # noqa: E402


def network_benchmark(name: str, resolution: int, run: bool, whole: bool) -> None:
    """World build, its memory, render per image and an autonomous run of ``name``."""
    network = build_network(name, seed=0)
    junctions = sum(1 for n in network.nodes if network.degree(n.label) >= 3)
    print(
        f"# {name}: {len(network.nodes)} nodes ({junctions} junctions), "
        f"{len(network.pipes)} pipes, one core"
    )
    rss = _rss_mib()
    wall, cpu = time.perf_counter(), time.process_time()
    world = World(network, seed=0, stream=not whole)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    built, pieces = world.pieces_built
    print(
        f"world build ({'whole' if whole else 'streamed'}): {wall:.2f} s wall, {cpu:.2f} s CPU, "
        f"{built} of {pieces} pieces, {world.triangle_count} triangles, "
        f"+{_rss_mib() - rss:.0f} MiB resident"
    )
    camera = CameraSpec(resolution_px=resolution)
    views = [((n.x_m + 1e-4, n.y_m + 1e-4, 0.05), 0.0) for n in network.nodes[:12]]
    wall, cpu = time.perf_counter(), time.process_time()
    for eye, yaw in views:  # builds the pieces they see, if the world is streamed
        world.render(eye, yaw, camera)
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    print(f"first pass over the {len(views)} views: {wall:.2f} s wall, {cpu:.2f} s CPU")
    images = {}
    for cull in (False, True) if whole else (True,):
        world.cull = cull
        walls, cpus, drawn, shots = [], [], [], []
        for eye, yaw in views:
            wall, cpu = time.perf_counter(), time.process_time()
            shots.append(world.render(eye, yaw, camera))
            walls.append(time.perf_counter() - wall)
            cpus.append(time.process_time() - cpu)
            drawn.append(world.drawn_bodies)
        images[cull] = shots
        print(
            f"render per image at {resolution}x{resolution}, culling {'on' if cull else 'off'}: "
            f"{statistics.median(walls) * 1000:.0f} ms wall, "
            f"{statistics.median(cpus) * 1000:.0f} ms CPU (median of {len(walls)}), "
            f"{statistics.median(drawn):.0f} bodies drawn (median)"
        )
    if whole:
        pairs = zip(images[False], images[True], strict=True)
        same = sum(bool((a == b).all()) for a, b in pairs)
        print(f"images identical with and without culling: {same} of {len(views)}")
    built, pieces = world.pieces_built
    print(
        f"after the views: {built} of {pieces} pieces built, +{_rss_mib() - rss:.0f} MiB "
        f"resident, peak {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MiB"
    )
    if run:
        wall, cpu = time.perf_counter(), time.process_time()
        result = autonomous_run(world, camera, seed=0)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        simulated = result.duration_ns / 1e9
        print(
            f"autonomous run at {resolution}x{resolution}: {result.status.value}, "
            f"{len(result.sweeps)} sweeps, {result.distance_m:.1f} m, {simulated:.0f} s simulated "
            f"in {wall:.1f} s wall ({simulated / wall:.1f}x real time), {cpu:.1f} s CPU "
            f"({simulated / cpu:.1f}x)"
        )
    world.close()


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--network", default=None, help="measure this network instead")
    parser.add_argument("--resolution", type=int, default=400, help="image size (400)")
    parser.add_argument("--no-run", action="store_true", help="skip the autonomous run")
    parser.add_argument(
        "--whole",
        action="store_true",
        help="build the world whole (stream=False) and compare culling off and on",
    )
    args = parser.parse_args()
    if args.network is not None:
        network_benchmark(args.network, args.resolution, not args.no_run, args.whole)
        return 0
    network = build_network("paper")
    start = time.perf_counter()
    world = World(network, seed=0, stream=False)
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
