"""Render docs/sim_montage.png: one camera sweep per node type, as the robot sees it.

Usage: ``python docs/make_montage.py`` (about half a minute). Rows: entry, T junction,
dead end, cross junction (the paper's network) and a corner (grid:2x2); six images
per row in sweep order, 60 degrees apart, 400x400 each shown at 200x200.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pipemap.sim import CameraSpec, World, build_network  # noqa: E402

ROWS = [
    ("paper", "S", "entry"),
    ("paper", "A", "T junction"),
    ("paper", "B", "dead end"),
    ("paper", "C", "cross junction"),
    ("grid:2x2", "r1c1", "corner"),
]


def main() -> int:
    camera = CameraSpec(resolution_px=400)
    strips = []
    worlds: dict[str, World] = {}
    for spec, label, kind in ROWS:
        if spec not in worlds:
            worlds[spec] = World(build_network(spec), seed=1)
        world = worlds[spec]
        node = world.network.node(label)
        heading = next(iter(world.network.pipe_headings(label).values())) + math.pi
        images = [
            cv2.resize(
                world.render(
                    (node.x_m + 1e-4, node.y_m + 1e-4, 0.05), heading - j * math.pi / 3, camera
                ),
                (200, 200),
            )
            for j in range(6)
        ]
        strip = np.hstack(images)
        white = (255, 255, 255)
        caption = f"{kind} ({spec} {label})"
        cv2.putText(strip, caption, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, white, 2)
        strips.append(strip)
    for world in worlds.values():
        world.close()
    out = ROOT / "docs" / "sim_montage.png"
    cv2.imwrite(str(out), cv2.cvtColor(np.vstack(strips), cv2.COLOR_RGB2BGR))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
