"""Junction meshes: exact cuts, inward normals, and no gaps (pure numpy, no PyBullet)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipemap.sim.geometry import Mesh, chamber_mesh, half_pipe_mesh, wall_start_m

R = 0.1
PHIS = np.linspace(0.0, 2.0 * math.pi, 97)


def _node_meshes(headings: list[float], half_length: float = 0.6) -> list[Mesh]:
    meshes = [
        half_pipe_mesh((0.0, 0.0), h, [o for o in headings if o != h], half_length, R, (0.0, 0.5))
        for h in headings
    ]
    chamber = chamber_mesh((0.0, 0.0), headings, R)
    if chamber is not None:
        meshes.append(chamber)
    return meshes


def _ray_hits(meshes: list[Mesh], origin: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Nearest hit distance of each ray over all triangles (inf if none): Moller-Trumbore."""
    tris = np.concatenate([m.vertices[m.indices] for m in meshes])  # (T, 3, 3)
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    best = np.full(len(directions), np.inf)
    for k, d in enumerate(directions):
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        t_vec = origin - v0
        u = np.einsum("ij,ij->i", t_vec, p) * inv
        q = np.cross(t_vec, e1)
        v = (q @ d) * inv
        t = np.einsum("ij,ij->i", e2, q) * inv
        hit = ok & (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1 + 1e-9) & (t > 1e-9)
        if hit.any():
            best[k] = t[hit].min()
    return best


def _directions(count: int, seed: int) -> np.ndarray:
    d = np.random.default_rng(seed).normal(size=(count, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def test_straight_through_pipes_cut_nothing() -> None:
    assert np.allclose(wall_start_m(0.0, [math.pi], R, PHIS), 0.0)


def test_t_branch_starts_on_the_steinmetz_curve() -> None:
    # Branch heading 0 (east), main pipe north-south: the branch wall at offset w
    # starts where it leaves the main cylinder, s = r |w . north|.
    start = wall_start_m(0.0, [math.pi / 2, -math.pi / 2], R, PHIS)
    w_north = np.sin(PHIS) * 1.0  # left normal of heading 0 is north
    assert np.allclose(start, R * np.abs(w_north), atol=1e-12)


def test_half_pipe_wall_is_on_its_cylinder_with_inward_normals() -> None:
    mesh = half_pipe_mesh((1.0, 2.0), 0.3, [0.3 + 2.0], 0.5, R, (0.0, 0.5))
    a = np.array([math.cos(0.3), math.sin(0.3), 0.0])
    rel = mesh.vertices - np.array([1.0, 2.0, R])
    radial = rel - np.outer(rel @ a, a)
    assert np.allclose(np.linalg.norm(radial, axis=1), R)
    assert np.allclose(np.einsum("ij,ij->i", mesh.normals, radial), -R)  # unit, pointing in
    assert mesh.uvs[:, 0].min() >= 0.0 and mesh.uvs[:, 0].max() == pytest.approx(0.5)


def test_wall_vertices_are_never_inside_another_pipe() -> None:
    headings = [0.0, 2.1, -2.0]  # a Y junction
    for h, mesh in zip(headings, _node_meshes(headings)[:3], strict=True):
        rel = mesh.vertices - np.array([0.0, 0.0, R])
        for other in headings:
            if other == h:
                continue
            b = np.array([math.cos(other), math.sin(other), 0.0])
            along = rel @ b
            dist2 = np.sum(rel**2, axis=1) - along**2
            assert not np.any((along > 1e-9) & (dist2 < R * R - 1e-9))


@pytest.mark.parametrize(
    ("headings", "span"),
    [([0.0], math.pi), ([0.0, math.pi / 2], math.pi / 2), ([0.0, 2.0], math.pi - 2.0)],
    ids=["dead-end", "right-angle-corner", "obtuse-corner"],
)
def test_chamber_keeps_the_longitudes_facing_away_from_every_pipe(
    headings: list[float], span: float
) -> None:
    mesh = chamber_mesh((0.0, 0.0), headings, R)
    assert mesh is not None
    n = (mesh.vertices - np.array([0.0, 0.0, R])) / R
    for h in headings:
        assert np.all(n @ np.array([math.cos(h), math.sin(h), 0.0]) <= 1e-9)
    # Longitudes measured from the middle of the open span: away from the pipes.
    away = -np.sum([[math.cos(h), math.sin(h)] for h in headings], axis=0)
    middle = math.atan2(away[1], away[0])
    horizontal = np.hypot(n[:, 0], n[:, 1]) > 0.5
    angles = np.arctan2(n[horizontal, 1], n[horizontal, 0]) - middle
    relative = np.remainder(angles + math.pi, 2 * math.pi) - math.pi
    assert np.ptp(relative) == pytest.approx(span, abs=1e-6)


@pytest.mark.parametrize(
    "headings",
    [
        [0.0, math.pi / 2, math.pi],
        [0.0, 2.0944, -2.0944],
        [0.0, math.pi / 2, math.pi, -math.pi / 2],
    ],
    ids=["T", "Y", "cross"],
)
def test_junctions_need_no_chamber(headings: list[float]) -> None:
    assert chamber_mesh((0.0, 0.0), headings, R) is None


@pytest.mark.parametrize(
    "headings",
    [
        [0.0],
        [0.0, math.pi / 2],
        [0.0, 1.9],
        [0.0, math.pi / 2, math.pi],
        [0.0, 2.0944, -2.0944],
        [0.0, math.pi / 2, math.pi, -math.pi / 2],
        [0.3, 1.5, 3.0],
    ],
    ids=["dead-end", "corner", "obtuse-corner", "T", "Y", "cross", "skewed-3"],
)
def test_no_gaps_rays_from_the_centre_hit_the_junction(headings: list[float]) -> None:
    meshes = _node_meshes(headings)
    centre = np.array([0.0, 0.0, R])
    dirs = _directions(300, seed=len(headings))
    # Rays running down a pipe (within its opening as seen from the centre) escape
    # through the far end; every other ray must hit the junction's own surface.
    axes = np.array([[math.cos(h), math.sin(h), 0.0] for h in headings])
    cos_to_axis = dirs @ axes.T
    down_a_pipe = np.any(cos_to_axis > math.cos(math.atan2(R, 0.6)) - 1e-3, axis=1)
    hits = _ray_hits(meshes, centre, dirs[~down_a_pipe])
    assert np.all(np.isfinite(hits)), f"{np.sum(~np.isfinite(hits))} rays escaped through a gap"
    assert hits.max() < 0.6 / math.cos(math.atan2(R, 0.6)) + 1e-6
