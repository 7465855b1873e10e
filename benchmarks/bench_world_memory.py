"""Where a world's memory and build time go: textures, visual meshes, collision meshes, bodies.

Builds the pieces of ``--network``'s world (every half-pipe and junction chamber, with
the meshes and textures ``sim/world.py`` makes) into a fresh headless PyBullet client,
one kind of object at a time, and prints JSON with the resident memory each kind adds
(MiB, ``/proc/self/status``) and the CPU time it takes:

- ``draw_textures``: drawing every texture image in numpy (seeded, as the world does);
- ``load_textures``: PyBullet's ``loadTexture`` of each (PNG files written first);
- ``visual_shapes``: ``createVisualShape`` of every mesh;
- ``collision_shapes``: ``createCollisionShape`` (concave triangle mesh) of every mesh;
- ``bodies``: ``createMultiBody`` joining them, with the texture set.

Then ``rebuild``: the whole world (``sim.world.World``) built and closed
``--rounds`` times in one process, the resident memory after each close: whether
disconnecting a client gives its memory back (a streamed world that rebuilds its
client as the robot moves needs it to).

Usage: ``python benchmarks/bench_world_memory.py [--network random:10] [--rounds 3]``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from resident import rss_mib as _rss_mib  # noqa: E402

from pipemap.sim import World, build_network  # noqa: E402
from pipemap.sim.geometry import Mesh, chamber_mesh, half_pipe_mesh  # noqa: E402
from pipemap.sim.network import Network  # noqa: E402
from pipemap.sim.textures import node_texture, pipe_texture  # noqa: E402
from pipemap.sim.world import pybullet  # noqa: E402  (imported quietly there)


def _pieces(network: Network, texture_px: int) -> tuple[list[Mesh], list[np.ndarray], list[int]]:
    """Every mesh of the world, every texture image, and each mesh's texture index."""
    rng = np.random.default_rng(0)
    radius = network.diameter_m / 2.0
    meshes: list[Mesh] = []
    images: list[np.ndarray] = []
    which: list[int] = []
    for pipe in network.pipes:
        length = network.length_m(pipe.a, pipe.b)
        images.append(
            pipe_texture(
                rng,
                width_px=texture_px * 2,
                height_px=texture_px,
                length_m=length,
                circumference_m=math.pi * network.diameter_m,
            )
        )
        for here, there, u in ((pipe.a, pipe.b, (0.0, 0.5)), (pipe.b, pipe.a, (1.0, 0.5))):
            headings = network.pipe_headings(here)
            node = network.node(here)
            others = [h for label, h in headings.items() if label != there]
            meshes.append(
                half_pipe_mesh(
                    (node.x_m, node.y_m), headings[there], others, length / 2.0, radius, u
                )
            )
            which.append(len(images) - 1)
    for node in network.nodes:
        chamber = chamber_mesh(
            (node.x_m, node.y_m), list(network.pipe_headings(node.label).values()), radius
        )
        if chamber is not None:
            images.append(node_texture(rng, texture_px, texture_px, radius_m=0.2))
            meshes.append(chamber)
            which.append(len(images) - 1)
    return meshes, images, which


def breakdown(name: str, texture_px: int) -> dict[str, Any]:
    """Memory and CPU time of each kind of object of ``name``'s world."""
    network = build_network(name, seed=0)
    out: dict[str, Any] = {
        "network": name,
        "nodes": len(network.nodes),
        "pipes": len(network.pipes),
    }
    client = pybullet.connect(pybullet.DIRECT)
    kw: dict[str, Any] = {"physicsClientId": client}
    steps: dict[str, dict[str, float]] = {}

    def step(label: str, rss: float, cpu: float) -> None:
        steps[label] = {
            "mib": round(_rss_mib() - rss, 1),
            "cpu_s": round(time.process_time() - cpu, 2),
        }

    rss, cpu = _rss_mib(), time.process_time()
    meshes, images, which = _pieces(network, texture_px)
    step("draw_textures_and_meshes", rss, cpu)
    out["meshes"] = len(meshes)
    out["triangles"] = sum(m.triangle_count for m in meshes)
    out["texture_images_mib"] = round(sum(i.nbytes for i in images) / 2**20, 1)
    with tempfile.TemporaryDirectory() as tmp:
        rss, cpu = _rss_mib(), time.process_time()
        tids = []
        for k, image in enumerate(images):
            path = Path(tmp) / f"t{k}.png"
            cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
            tids.append(int(pybullet.loadTexture(str(path), **kw)))
        step("load_textures", rss, cpu)
    del images
    rss, cpu = _rss_mib(), time.process_time()
    visuals = [
        pybullet.createVisualShape(
            pybullet.GEOM_MESH,
            vertices=m.vertices.tolist(),
            indices=m.indices.ravel().tolist(),
            uvs=m.uvs.tolist(),
            normals=m.normals.tolist(),
            **kw,
        )
        for m in meshes
    ]
    step("visual_shapes", rss, cpu)
    rss, cpu = _rss_mib(), time.process_time()
    collisions = [
        pybullet.createCollisionShape(
            pybullet.GEOM_MESH,
            vertices=m.vertices.tolist(),
            indices=m.indices.ravel().tolist(),
            flags=pybullet.GEOM_FORCE_CONCAVE_TRIMESH,
            **kw,
        )
        for m in meshes
    ]
    step("collision_shapes", rss, cpu)
    rss, cpu = _rss_mib(), time.process_time()
    for visual, collision, k in zip(visuals, collisions, which, strict=True):
        body = pybullet.createMultiBody(
            baseMass=0.0, baseCollisionShapeIndex=collision, baseVisualShapeIndex=visual, **kw
        )
        pybullet.changeVisualShape(body, -1, textureUniqueId=tids[k], **kw)
    step("bodies", rss, cpu)
    pybullet.disconnect(**kw)
    out["steps"] = steps
    out["mib_per_node"] = round(sum(s["mib"] for s in steps.values()) / len(network.nodes), 1)
    return out


def rebuild(name: str, rounds: int) -> dict[str, Any]:
    """Resident memory after each of ``rounds`` builds and closes of the whole world."""
    network = build_network(name, seed=0)
    start = _rss_mib()
    after_build, after_close = [], []
    for _ in range(rounds):
        world = World(network, seed=0)
        after_build.append(round(_rss_mib() - start, 1))
        world.close()
        after_close.append(round(_rss_mib() - start, 1))
    return {"network": name, "rss_after_build_mib": after_build, "rss_after_close_mib": after_close}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--network", default="random:10")
    parser.add_argument("--texture-px", type=int, default=512)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    result = {
        "breakdown": breakdown(args.network, args.texture_px),
        "rebuild": rebuild(args.network, args.rounds),
    }
    print(json.dumps(result, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
