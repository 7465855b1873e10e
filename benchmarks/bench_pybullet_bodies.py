"""What PyBullet keeps when a world's pieces are removed, and what a pool of bodies costs.

A streamed world would build the pieces near the robot and let go of those behind
it. ``sim/world.py`` never removes a body: PyBullet was seen to keep mesh memory of
removed bodies. This measures it, in one headless client, with a real half-pipe mesh
of the simulator (1 m, the pipes' diameter) and a 1024x512 texture, for ``--rounds``
rounds of ``--pieces`` pieces each:

- ``remove``: each round creates the pieces (visual shape, concave collision mesh,
  body, a new texture) and then removes every body;
- ``pool``: the pieces are created once; each round moves every body elsewhere
  (``resetBasePositionAndOrientation``) and gives it a texture from a pool made once
  (``changeVisualShape``), as a pool of bodies reused by a streamed world would.

Prints JSON: the resident memory (MiB, ``/proc/self/status``) after each round and
the growth per round after the first.

Usage: ``python benchmarks/bench_pybullet_bodies.py [--pieces 20] [--rounds 6]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from resident import rss_mib as _rss_mib  # noqa: E402

from pipemap.sim.geometry import Mesh, half_pipe_mesh  # noqa: E402
from pipemap.sim.world import pybullet  # noqa: E402  (imported quietly there)
from pipemap.sim.world_pieces import add_body  # noqa: E402


def _texture(client: int, folder: Path, name: str, rng: np.random.Generator) -> int:
    path = folder / f"{name}.png"
    image = rng.integers(0, 256, size=(512, 1024, 3), dtype=np.uint8)
    cv2.imwrite(str(path), image)
    return int(pybullet.loadTexture(str(path), physicsClientId=client))


def _body(client: int, mesh: Mesh, texture: int, x_m: float) -> int:
    body = add_body(pybullet, client, mesh, texture)
    pybullet.resetBasePositionAndOrientation(
        body, [x_m, 0.0, 0.0], [0, 0, 0, 1], physicsClientId=client
    )
    return body


def run(mode: str, pieces: int, rounds: int) -> dict[str, object]:
    """Resident memory after each round of ``mode`` (``remove`` or ``pool``)."""
    client = pybullet.connect(pybullet.DIRECT)
    rng = np.random.default_rng(0)
    mesh = half_pipe_mesh((0.0, 0.0), 0.0, [], 0.5, 0.1, (0.0, 0.5))
    start = _rss_mib()
    after: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if mode == "pool":
            textures = [_texture(client, folder, f"t{k}", rng) for k in range(pieces)]
            bodies = [_body(client, mesh, textures[k], 2.0 * k) for k in range(pieces)]
        for r in range(rounds):
            if mode == "remove":
                made = [
                    _body(client, mesh, _texture(client, folder, f"r{r}-{k}", rng), 2.0 * k)
                    for k in range(pieces)
                ]
                for body in made:
                    pybullet.removeBody(body, physicsClientId=client)
            else:
                for k, body in enumerate(bodies):
                    pybullet.resetBasePositionAndOrientation(
                        body, [2.0 * k + r, 1.0, 0.0], [0, 0, 0, 1], physicsClientId=client
                    )
                    pybullet.changeVisualShape(
                        body,
                        -1,
                        textureUniqueId=textures[(k + r) % pieces],
                        physicsClientId=client,
                    )
            after.append(round(_rss_mib() - start, 1))
    pybullet.disconnect(physicsClientId=client)
    growth = (after[-1] - after[0]) / max(1, rounds - 1)
    return {
        "mode": mode,
        "pieces": pieces,
        "triangles_per_piece": mesh.triangle_count,
        "rss_after_round_mib": after,
        "growth_per_round_mib": round(growth, 1),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pieces", type=int, default=20)
    parser.add_argument("--rounds", type=int, default=6)
    args = parser.parse_args()
    results = [run(mode, args.pieces, args.rounds) for mode in ("remove", "pool")]
    print(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
