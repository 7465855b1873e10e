"""The pieces of a world (half-pipes, junction chambers), built into its PyBullet client
when first needed.

A piece is a pipe (its two half-pipe bodies, one texture) or a node's chamber. Each
piece draws its texture from its own generator, spawned from the world's seed in a
fixed order (every pipe, then every node), and a shared look's texture from its own
seed (:class:`sim.lookalike.LookTextures`): so a piece looks the same whether it is
built first, last, or never with the others, and a world that builds its pieces as
the robot comes near them (``World(stream=True)``) draws exactly the images of one
that built them all at once.

A piece's texture file is written, read by PyBullet and removed at once, so a process
killed during a run leaves at most one file behind (and the next world removes the
folder of a process that no longer runs).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from pipemap.errors import WriteError
from pipemap.sim.geometry import Mesh, chamber_mesh, chamber_u_origin_rad, half_pipe_mesh
from pipemap.sim.lookalike import LookAlike, LookTextures
from pipemap.sim.network import Network
from pipemap.sim.textures import node_texture, pipe_texture

__all__ = ["Pieces", "add_body"]


class Pieces:
    """Builds the pieces of ``network`` into ``client`` on demand, each at most once."""

    def __init__(
        self,
        pybullet: Any,
        client: int,
        network: Network,
        looks: LookAlike,
        seed: int,
        texture_px: int,
        folder: Path,
    ) -> None:
        self._pb = pybullet
        self._client = client
        self.network = network
        self._worn = looks.looks
        self._shared = LookTextures(network, looks, seed, texture_px)
        self._texture_px = texture_px
        self._folder = folder
        rng = np.random.default_rng(seed)
        # Spawned in this order as ever: a texture does not change when another part
        # of the network does, nor when the pieces are built in another order.
        self._pipe_rngs = rng.spawn(len(network.pipes))
        self._node_rngs = rng.spawn(len(network.nodes))
        self._node_index = {n.label: k for k, n in enumerate(network.nodes)}
        self._incident: dict[str, list[int]] = {n.label: [] for n in network.nodes}
        for k, pipe in enumerate(network.pipes):
            self._incident[pipe.a].append(k)
            self._incident[pipe.b].append(k)
        self._look_tids: dict[str, int] = {}
        self._pipes_built: set[int] = set()
        self._nodes_built: set[int] = set()
        #: Bodies of each node (its chamber and both halves of each of its pipes) and
        #: of each pipe, as far as they are built.
        self.node_bodies: dict[str, list[int]] = {n.label: [] for n in network.nodes}
        self.pipe_bodies: dict[tuple[str, str], list[int]] = {(p.a, p.b): [] for p in network.pipes}
        self.triangle_count = 0
        # Plan boxes that hold each piece (a pipe's half-pipes and a chamber stay
        # within a diameter of the pipe's axis and the node's centre).
        pad = network.diameter_m + 0.05
        xy = np.array([(n.x_m, n.y_m) for n in network.nodes], dtype=np.float64)
        ends = np.array(
            [(self._node_index[p.a], self._node_index[p.b]) for p in network.pipes], dtype=np.intp
        ).reshape(-1, 2)
        self._pipe_lo = np.minimum(xy[ends[:, 0]], xy[ends[:, 1]]) - pad
        self._pipe_hi = np.maximum(xy[ends[:, 0]], xy[ends[:, 1]]) + pad
        self._node_lo, self._node_hi = xy - pad, xy + pad

    @property
    def pieces(self) -> int:
        """Pieces in all: every pipe and every node."""
        return len(self.network.pipes) + len(self.network.nodes)

    @property
    def built(self) -> int:
        """Pieces built so far."""
        return len(self._pipes_built) + len(self._nodes_built)

    def everything(self, on_build: Callable[[int, int], None] | None = None) -> None:
        """Build every piece not built yet: every pipe, then every node."""
        pieces = self.pieces
        for k in range(len(self.network.pipes)):
            if on_build is not None:
                on_build(k, pieces)
            self.pipe(k)
        for k, node in enumerate(self.network.nodes):
            if on_build is not None:
                on_build(len(self.network.pipes) + k, pieces)
            self.chamber(node.label)
        if on_build is not None:
            on_build(pieces, pieces)

    def parts(self, nodes: set[str], pipes: set[tuple[str, str]]) -> None:
        """Build what drawing ``nodes`` (with their pipes) and ``pipes`` takes."""
        index = self._pipe_index()
        for label in nodes:
            self.chamber(label)
            for k in self._incident[label]:
                self.pipe(k)
        for key in pipes:
            self.pipe(index[key])

    def near(self, lo_xy: np.ndarray, hi_xy: np.ndarray) -> None:
        """Build every piece that may reach into the plan box ``lo_xy``..``hi_xy``."""
        pipes = np.flatnonzero(
            np.all(self._pipe_lo <= hi_xy, axis=1) & np.all(self._pipe_hi >= lo_xy, axis=1)
        )
        nodes = np.flatnonzero(
            np.all(self._node_lo <= hi_xy, axis=1) & np.all(self._node_hi >= lo_xy, axis=1)
        )
        for k in pipes:
            self.pipe(int(k))
        for k in nodes:
            self.chamber(self.network.nodes[int(k)].label)

    def _pipe_index(self) -> dict[tuple[str, str], int]:
        if not hasattr(self, "_index"):
            self._index = {(p.a, p.b): k for k, p in enumerate(self.network.pipes)}
        return self._index

    # -- one piece ----------------------------------------------------------------------

    def pipe(self, k: int) -> None:
        """Build pipe ``k``'s two half-pipes (once)."""
        if k in self._pipes_built:
            return
        self._pipes_built.add(k)
        net, worn = self.network, self._worn
        pipe = net.pipes[k]
        length = net.length_m(pipe.a, pipe.b)
        own = None
        if not (pipe.a in worn and pipe.b in worn):
            texture = pipe_texture(
                self._pipe_rngs[k],
                width_px=self._texture_px * 2,
                height_px=self._texture_px,
                length_m=length,
                circumference_m=math.pi * net.diameter_m,
            )
            own = self._texture(f"pipe-{pipe.a}-{pipe.b}", texture)
        for here, there, u_range in ((pipe.a, pipe.b, (0.0, 0.5)), (pipe.b, pipe.a, (1.0, 0.5))):
            tid = own
            if here in worn:  # the half at a node that wears a shared look
                name, image, u_range = self._shared.half_pipe(here, there)
                if name not in self._look_tids:
                    self._look_tids[name] = self._texture(name, image)
                tid = self._look_tids[name]
            assert tid is not None
            headings = net.pipe_headings(here)
            node = net.node(here)
            others = [h for label, h in headings.items() if label != there]
            mesh = half_pipe_mesh(
                (node.x_m, node.y_m),
                headings[there],
                others,
                length / 2.0,
                net.diameter_m / 2.0,
                u_range,
            )
            body = self._add(mesh, tid)
            self.pipe_bodies[(pipe.a, pipe.b)].append(body)
            self.node_bodies[pipe.a].append(body)
            self.node_bodies[pipe.b].append(body)

    def chamber(self, label: str) -> None:
        """Build the chamber of node ``label`` (once); a node whose pipes close it has none."""
        k = self._node_index[label]
        if k in self._nodes_built:
            return
        self._nodes_built.add(k)
        node = self.network.node(label)
        # The entry is closed too: the launch pit's wall, not open air, which would
        # render as a black half-image that looks like any dark view.
        directions = list(self.network.pipe_headings(label).values())
        chamber = chamber_mesh((node.x_m, node.y_m), directions, self.network.diameter_m / 2.0)
        if chamber is None:
            return
        # Drawn for a 0.2 m sphere, so the chamber's stains and deposits come out twice
        # as coarse as the pipes'. At the true scale the fine detail of the end caps
        # washes out at 400 px: on the paper tour two different dead ends then scored
        # 0.366, over the 0.36 threshold (0.339 as drawn).
        origin = chamber_u_origin_rad(directions)
        if label in self._worn and origin is not None:
            texture = self._shared.chamber(label, origin)
        else:
            texture = node_texture(
                self._node_rngs[k], self._texture_px, self._texture_px, radius_m=0.2
            )
        tid = self._texture(f"node-{label}", texture)
        self.node_bodies[label].append(self._add(chamber, tid))

    def _add(self, mesh: Mesh, texture_id: int) -> int:
        self.triangle_count += mesh.triangle_count
        return add_body(self._pb, self._client, mesh, texture_id)

    def _texture(self, name: str, image: np.ndarray) -> int:
        path = self._folder / f"{name}.png"
        # Encoded in memory and written by Python: a full disk is one line (exit 3),
        # never libpng's complaint and a texture PyBullet cannot load.
        _, png = cv2.imencode(".png", cv2.cvtColor(image, cv2.COLOR_RGB2BGR))
        try:
            path.write_bytes(png.tobytes())
        except OSError as exc:
            raise WriteError(
                f"{path.parent}: cannot write the world's texture files ({exc.strerror or exc})"
            ) from None
        try:
            return int(self._pb.loadTexture(str(path), physicsClientId=self._client))
        finally:
            path.unlink(missing_ok=True)


def add_body(pb: Any, client: int, mesh: Mesh, texture_id: int) -> int:
    """A static body of ``mesh`` (visual and concave collision mesh) with a texture."""
    kwargs: dict[str, Any] = {"physicsClientId": client}
    visual = pb.createVisualShape(
        pb.GEOM_MESH,
        vertices=mesh.vertices.tolist(),
        indices=mesh.indices.ravel().tolist(),
        uvs=mesh.uvs.tolist(),
        normals=mesh.normals.tolist(),
        **kwargs,
    )
    collision = pb.createCollisionShape(
        pb.GEOM_MESH,
        vertices=mesh.vertices.tolist(),
        indices=mesh.indices.ravel().tolist(),
        flags=pb.GEOM_FORCE_CONCAVE_TRIMESH,
        **kwargs,
    )
    body = pb.createMultiBody(
        baseMass=0.0, baseCollisionShapeIndex=collision, baseVisualShapeIndex=visual, **kwargs
    )
    pb.changeVisualShape(body, -1, textureUniqueId=texture_id, **kwargs)
    return int(body)
