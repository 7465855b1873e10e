"""The world in a child process (``--world-memory``): memory of the whole process tree,
time, and the cost of sending images and range rays across the pipe.

    python benchmarks/bench_world_process.py tree -- pipemap record --network random:8 ...
    python benchmarks/bench_world_process.py ipc [--resolution PX] [--network NAME]

``tree`` runs a command and samples, twice a second, the resident memory of it and
of every process below it (the log writer, the world's child), and prints JSON: wall
seconds, CPU seconds of the tree (``RUSAGE_CHILDREN``), the peak of the tree's total
resident memory and the peak of its largest process, and the exit status. GNU
``time -v`` reports the largest single process only, which misses the world's child.

``ipc`` draws the same views and range readings in a world in this process and in a
:class:`sim.world_process.WorldProcess` (every piece built first, so that only the
transport differs) and prints JSON: milliseconds per image and per range reading,
each way, and the difference, the cost of the pipe.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np


def _tree_rss_mib(root: int) -> tuple[float, float]:
    """(total, largest) resident memory of ``root`` and every process below it, MiB."""
    children: dict[int, list[int]] = {}
    rss: dict[int, float] = {}
    page = os.sysconf("SC_PAGE_SIZE") / (1024 * 1024)
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            statm = (entry / "statm").read_text().split()
            parent = int(stat[stat.rindex(")") + 2 :].split()[1])
            resident = int(statm[1]) * page
        except (OSError, ValueError, IndexError):  # a process that ended as it was read
            continue
        children.setdefault(parent, []).append(int(entry.name))
        rss[int(entry.name)] = resident
    total, largest, todo = 0.0, 0.0, [root]
    while todo:
        pid = todo.pop()
        total += rss.get(pid, 0.0)
        largest = max(largest, rss.get(pid, 0.0))
        todo.extend(children.get(pid, []))
    return total, largest


def tree(command: list[str]) -> dict[str, object]:
    """Run ``command``, sampling its process tree's memory."""
    start = time.perf_counter()
    process = subprocess.Popen(command)
    peak_total = peak_largest = 0.0
    while process.poll() is None:
        total, largest = _tree_rss_mib(process.pid)
        peak_total, peak_largest = max(peak_total, total), max(peak_largest, largest)
        time.sleep(0.5)
    wall = time.perf_counter() - start
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return {
        "command": " ".join(command),
        "exit": process.returncode,
        "wall_s": round(wall, 1),
        "cpu_s": round(usage.ru_utime + usage.ru_stime, 1),
        "peak_tree_mib": round(peak_total),
        "peak_largest_process_mib": round(peak_largest),
    }


def ipc(network_name: str, resolution: int, repeat: int) -> dict[str, object]:
    """Per image and per range reading, in this process and across the pipe."""
    from pipemap.sim import CameraSpec, World, build_network
    from pipemap.sim.world_process import WorldProcess

    network = build_network(network_name, seed=0)
    camera = CameraSpec(resolution_px=resolution)
    views = []
    for node in network.nodes[:4]:
        for heading in network.pipe_headings(node.label).values():
            eye = (node.x_m + 1e-4, node.y_m + 1e-4, 0.06)
            views.extend((eye, heading + j * math.pi / 3) for j in range(6))
    rays = [
        (
            np.array([eye] * 3),
            np.array([[math.cos(y + a), math.sin(y + a), 0.0] for a in (0, 0.6, -0.6)]),
        )
        for eye, y in views
    ]
    out: dict[str, object] = {
        "network": network_name,
        "resolution_px": resolution,
        "views": len(views),
    }
    for name, make in (
        ("in_process", lambda: World(network, seed=0, stream=False)),
        ("child", lambda: WorldProcess(network, seed=0, stream=False)),
    ):
        with make() as world:
            for eye, yaw in views:  # warm: the culling's first pass, the caches
                world.render(eye, yaw, camera)
            best_image = best_ray = math.inf
            for _ in range(repeat):
                t = time.perf_counter()
                for eye, yaw in views:
                    world.render(eye, yaw, camera)
                best_image = min(best_image, (time.perf_counter() - t) / len(views))
                t = time.perf_counter()
                for _ in range(10):
                    for origins, dirs in rays:
                        world.ray_distances_m(origins, dirs, 1.2)
                best_ray = min(best_ray, (time.perf_counter() - t) / (10 * len(rays)))
            out[f"{name}_ms_per_image"] = round(best_image * 1000, 3)
            out[f"{name}_ms_per_range_reading"] = round(best_ray * 1000, 3)
    for what in ("image", "range_reading"):
        child = out[f"child_ms_per_{what}"]
        here = out[f"in_process_ms_per_{what}"]
        assert isinstance(child, float) and isinstance(here, float)
        out[f"pipe_ms_per_{what}"] = round(child - here, 3)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    p = sub.add_parser("tree")
    p.add_argument("command", nargs=argparse.REMAINDER)
    p = sub.add_parser("ipc")
    p.add_argument("--network", default="paper")
    p.add_argument("--resolution", type=int, default=96)
    p.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    if args.what == "tree":
        command = args.command[1:] if args.command[:1] == ["--"] else args.command
        result = tree(command)
    else:
        result = ipc(args.network, args.resolution, args.repeat)
    print(json.dumps(result))
    sys.exit(0)


if __name__ == "__main__":
    main()
