"""Meshes of the inside of a pipe network, generated in code.

Every pipe between nodes u and v is split at its middle: each node owns the half
next to it. The pipe axis runs at height ``r`` (the floor is at z = 0). Around each
node the half-pipes meet, and a sphere of radius ``r`` at the node centre closes
what they leave open. Both cuts are exact:

* A point of half-pipe A's wall, ``s`` along A from the centre, at the unit
  offset ``w`` from A's axis, lies inside another half-pipe B (direction ``b``)
  exactly when ``s < r (w . b) / (1 - a . b)``. So each wall column starts at the
  largest such bound over the node's other pipes, which is the cylinder-cylinder
  intersection curve (the Steinmetz curve of a T junction).
* A point ``r n`` of the sphere lies inside half-pipe B exactly when ``n . b > 0``.
  All pipes are horizontal, so the sphere that no pipe covers is a set of whole
  meridians: the longitudes facing away from every pipe. That is the end cap of a
  dead end and the outer knuckle of a corner, and nothing at all for a T, Y or
  cross junction, whose pipes close the junction by themselves.

The entry is capped like a dead end (the wall of the launch pit). Normals point
into the pipe (towards the camera). Texture coordinates: ``u`` runs along a pipe over its
whole length (both halves share one texture), ``v`` around it from the floor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Mesh", "chamber_mesh", "chamber_u_origin_rad", "half_pipe_mesh", "wall_start_m"]


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh: ``vertices`` and ``normals`` (V, 3), ``uvs`` (V, 2), ``indices`` (T, 3)."""

    vertices: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    indices: np.ndarray

    @property
    def triangle_count(self) -> int:
        """Number of triangles."""
        return int(self.indices.shape[0])


def _grid_indices(rows: int, cols: int) -> np.ndarray:
    """Two triangles per cell of a (rows+1) x (cols+1) vertex grid, wound to face inwards."""
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = (r * (cols + 1) + c).ravel()
    b, d = a + 1, a + cols + 1
    e = d + 1
    return (
        np.stack([np.stack([a, d, b], 1), np.stack([b, d, e], 1)], 1)
        .reshape(-1, 3)
        .astype(np.int32)
    )


def _frame(heading_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Unit axis ``a`` of a pipe leaving at ``heading_rad`` and its left normal ``u``."""
    a = np.array([math.cos(heading_rad), math.sin(heading_rad), 0.0])
    u = np.array([-math.sin(heading_rad), math.cos(heading_rad), 0.0])
    return a, u


def _wall_offsets(heading_rad: float, phis: np.ndarray) -> np.ndarray:
    """Unit offsets from the axis around the wall: phi = 0 at the floor, pi at the crown."""
    _, u = _frame(heading_rad)
    up = np.array([0.0, 0.0, 1.0])
    offsets: np.ndarray = -np.cos(phis)[:, None] * up + np.sin(phis)[:, None] * u
    return offsets


def wall_start_m(
    heading_rad: float, others_rad: list[float], radius_m: float, phis: np.ndarray
) -> np.ndarray:
    """Where the wall of one half-pipe starts, per wall angle, given the node's other pipes."""
    a, _ = _frame(heading_rad)
    w = _wall_offsets(heading_rad, phis)
    start = np.zeros(phis.shape)
    for other in others_rad:
        b, _ = _frame(other)
        along = 1.0 - float(a @ b)
        if along < 1e-9:  # the same direction: refused by network validation
            continue
        start = np.maximum(start, radius_m * (w @ b) / along)
    return start


def half_pipe_mesh(
    centre_xy_m: tuple[float, float],
    heading_rad: float,
    others_rad: list[float],
    half_length_m: float,
    radius_m: float,
    u_range: tuple[float, float],
    around: int = 96,
    step_m: float = 0.02,
) -> Mesh:
    """The wall of the half of a pipe that leaves a node centre at ``heading_rad``.

    ``others_rad`` are the headings of the node's other pipes (they cut the wall near
    the centre); ``u_range`` is the texture ``u`` at the centre and at the far end.
    """
    phis = np.linspace(0.0, 2.0 * math.pi, around + 1)
    start = wall_start_m(heading_rad, others_rad, radius_m, phis)
    rows = max(2, int(math.ceil(half_length_m / step_m)))
    t = np.linspace(0.0, 1.0, rows + 1)[:, None]
    s = start[None, :] + t * (half_length_m - start[None, :])  # (rows+1, around+1)
    a, _ = _frame(heading_rad)
    w = _wall_offsets(heading_rad, phis)  # (around+1, 3)
    centre = np.array([centre_xy_m[0], centre_xy_m[1], radius_m])
    vertices = centre + s[..., None] * a + radius_m * w[None, :, :]
    normals = np.broadcast_to(-w[None, :, :], vertices.shape)
    u0, u1 = u_range
    uu = u0 + (u1 - u0) * s / half_length_m
    vv = np.broadcast_to(phis[None, :] / (2.0 * math.pi), s.shape)
    return Mesh(
        vertices=vertices.reshape(-1, 3),
        normals=np.ascontiguousarray(normals.reshape(-1, 3)),
        uvs=np.stack([uu, vv], -1).reshape(-1, 2),
        indices=_grid_indices(rows, around),
    )


def _open_longitudes(headings_rad: list[float]) -> tuple[float, float] | None:
    """The longitude interval facing away from every pipe, or None if there is none."""
    # Facing away from heading h means longitude in [h + pi/2, h + 3 pi/2]. Intersect
    # these half circles, measured from the first one's start.
    lo, hi = headings_rad[0] + math.pi / 2, headings_rad[0] + 3 * math.pi / 2
    for h in headings_rad[1:]:
        start = lo + math.remainder(h + math.pi / 2 - lo, 2 * math.pi)
        lo, hi = max(lo, start), min(hi, start + math.pi)
    return (lo, hi) if hi - lo > 1e-6 else None


def chamber_u_origin_rad(headings_rad: list[float]) -> float | None:
    """The longitude at texture ``u = 0`` of :func:`chamber_mesh` for the same headings
    (in the same order), or None when there is no chamber."""
    span = _open_longitudes(headings_rad)
    return None if span is None else span[0]


def chamber_mesh(
    centre_xy_m: tuple[float, float],
    headings_rad: list[float],
    radius_m: float,
    segments: int = 48,
) -> Mesh | None:
    """The part of the node's sphere that no pipe covers, or None if the pipes close it."""
    span = _open_longitudes(headings_rad)
    if span is None:
        return None
    lo, hi = span
    cols = max(2, int(math.ceil(segments * (hi - lo) / math.pi)))
    lon = np.linspace(lo, hi, cols + 1)
    lat = np.linspace(-math.pi / 2, math.pi / 2, segments + 1)
    la, lo_grid = np.meshgrid(lat, lon, indexing="ij")  # (segments+1, cols+1)
    n = np.stack([np.cos(la) * np.cos(lo_grid), np.cos(la) * np.sin(lo_grid), np.sin(la)], -1)
    centre = np.array([centre_xy_m[0], centre_xy_m[1], radius_m])
    vertices = centre + radius_m * n
    uvs = np.stack([(lo_grid - lo) / (2 * math.pi), (la + math.pi / 2) / math.pi], -1)
    indices = _grid_indices(segments, cols)
    return Mesh(
        vertices=vertices.reshape(-1, 3),
        normals=(-n).reshape(-1, 3),
        uvs=uvs.reshape(-1, 2),
        indices=np.ascontiguousarray(indices),
    )
