"""Town-scale seeded networks: ``random:N`` and ``tree:N`` for N above 100.

:mod:`sim.random_layout` draws a whole layout and throws it away when any one node
fails a rule, so its chance of success falls with every node (``random:200`` found
no valid layout in 2000 draws). Its networks are kept for N up to
:data:`TOWN_ABOVE` (the logs, tests and benchmarks name them); above, this module
draws the same kind of layout but repairs it locally:

- the square is cut into districts of about :data:`_DISTRICT_NODES` nodes' worth,
  each with its own node spacing drawn log-uniformly from 1.25 to 12 pipe spacings
  (:class:`_Field`), so pipes run from 1 to 20 spacings (1-20 m at the default 1 m),
  short in a dense district, long in a sparse one, as a town's mains between manholes;
- points are scattered by dart throwing over a grid of cells, each dart kept with a
  chance that makes a district's density follow its spacing and checked against its
  neighbours only; pipes are checked against the pipes and nodes near them through
  the same kind of grid (:class:`_Grid`), and none is longer than 20 spacings;
- a spanning tree is grown from the Delaunay edges in a drawn order, then loops,
  about one pipe in six beyond the tree (``random``), as a town's mains close;
- a node with two pipes that go nearly straight on (a corner the robot could not
  tell from the follower's weave) gets a third pipe if one fits, else is pushed
  sideways until it turns by at least 20 degrees; only a layout that still fails
  is drawn again.

The same seed gives the same network; the rules are those of
:class:`~pipemap.sim.network_model.Network` with the wider margins of
:mod:`sim.random_layout`.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from pipemap.sim.network_model import (
    MIN_JUNCTION_ANGLE_RAD,
    MIN_PIPE_DIAMETERS,
    Network,
)
from pipemap.sim.planar import heading_rad, point_segment_distance_m, segments_touch, wrap_rad
from pipemap.sim.random_layout import (
    _GEN_CLEARANCE_DIAMETERS,
    _GEN_STRAIGHT_RAD,
    _candidate_edges,
    first_draw,
    grow_tree,
    labelled,
    min_gap_m,
)

__all__ = ["TOWN_ABOVE", "town_network"]

#: ``random:N`` and ``tree:N`` above this many nodes are drawn here.
TOWN_ABOVE = 100
_MAX_ATTEMPTS = 20
#: Passes over the straight nodes: a repair can straighten a neighbour, fixed next pass.
_STRAIGHT_PASSES = 4
#: Shortest and longest district spacing, and longest pipe, in pipe spacings: with
#: the closest two nodes 0.8 of their spacing apart, pipes run 1 to 20 spacings.
_DENSE, _SPARSE, _LONGEST = 1.25, 12.0, 20.0
#: About this many nodes' worth of area makes a district.
_DISTRICT_NODES = 30
#: Sideways pushes tried on a straight node, in lengths of its shorter pipe.
_PUSHES = (0.12, -0.12, 0.2, -0.2, 0.3, -0.3)

XY = tuple[float, float]


class _Grid:
    """Square cells of side ``cell_m``, each listing the items whose box overlaps it."""

    def __init__(self, cell_m: float) -> None:
        self.cell_m = cell_m
        self.cells: dict[tuple[int, int], list[int]] = {}

    def _span(self, lo: XY, hi: XY) -> Iterator[tuple[int, int]]:
        c = self.cell_m
        for i in range(math.floor(lo[0] / c), math.floor(hi[0] / c) + 1):
            for j in range(math.floor(lo[1] / c), math.floor(hi[1] / c) + 1):
                yield i, j

    def insert(self, item: int, lo: XY, hi: XY) -> None:
        for key in self._span(lo, hi):
            self.cells.setdefault(key, []).append(item)

    def remove(self, item: int, lo: XY, hi: XY) -> None:
        for key in self._span(lo, hi):
            self.cells[key].remove(item)

    def near(self, lo: XY, hi: XY) -> set[int]:
        found: set[int] = set()
        for key in self._span(lo, hi):
            found.update(self.cells.get(key, ()))
        return found


def _box(a: XY, b: XY, margin_m: float) -> tuple[XY, XY]:
    lo = (min(a[0], b[0]) - margin_m, min(a[1], b[1]) - margin_m)
    hi = (max(a[0], b[0]) + margin_m, max(a[1], b[1]) + margin_m)
    return lo, hi


class _Field:
    """A square of ``districts`` x ``districts`` districts, each with its own node
    spacing (m), sized so that ``n`` nodes fill it as densely as :mod:`sim.random_layout`
    fills its square."""

    def __init__(self, n: int, rng: np.random.Generator, spacing_m: float) -> None:
        self.districts = max(1, round(math.sqrt(n / _DISTRICT_NODES)))
        lo, hi = math.log(_DENSE), math.log(_SPARSE)
        draws = rng.uniform(lo, hi, size=self.districts**2)
        self.spacing_m = np.round(spacing_m * np.exp(draws), 3)
        self.dense_m = _DENSE * spacing_m
        per_m2 = float(np.sum(1.0 / (1.96 * self.spacing_m**2)))
        self.side_m = self.districts * math.sqrt(n / per_m2)

    def at(self, p: XY) -> float:
        """The spacing of the district holding ``p``."""
        d = self.districts
        i = min(d - 1, max(0, math.floor(p[0] / self.side_m * d)))
        j = min(d - 1, max(0, math.floor(p[1] / self.side_m * d)))
        return float(self.spacing_m[i * d + j])


def _scatter(
    n: int, rng: np.random.Generator, field: _Field, diameter_m: float
) -> np.ndarray | None:
    """``n`` points in the field's square by dart throwing: a dart is kept with a
    chance of (densest spacing / its district's)^2, and two points are at least the
    smaller of their districts' gaps apart."""
    grid = _Grid(min_gap_m(field.dense_m, diameter_m))
    pts: list[XY] = []
    gaps: list[float] = []
    keep = float(np.mean((field.dense_m / field.spacing_m) ** 2))
    darts = rng.uniform(0.0, field.side_m, size=(math.ceil(60 * n / keep), 2))
    chances = rng.uniform(0.0, 1.0, size=len(darts))
    for (x, y), chance in zip(darts, chances, strict=True):
        cand = (float(x), float(y))
        spacing = field.at(cand)
        if chance >= (field.dense_m / spacing) ** 2:
            continue
        gap = min_gap_m(spacing, diameter_m)
        lo, hi = _box(cand, cand, gap)
        if all(math.dist(cand, pts[k]) >= min(gap, gaps[k]) for k in grid.near(lo, hi)):
            grid.insert(len(pts), cand, cand)
            pts.append(cand)
            gaps.append(gap)
            if len(pts) == n:
                return np.round(np.array(pts), 3)
    return None


class _TownBuilder:
    """Pipes added one at a time, each checked against the pipes and nodes near it."""

    def __init__(self, pts: np.ndarray, diameter_m: float, cell_m: float, longest_m: float) -> None:
        self.xy: list[XY] = [(float(x), float(y)) for x, y in pts]
        self.diameter_m = diameter_m
        self.longest_m = longest_m
        self.clearance_m = _GEN_CLEARANCE_DIAMETERS * diameter_m
        self.heads: list[dict[int, float]] = [{} for _ in self.xy]
        self.edges: dict[int, tuple[int, int]] = {}
        self.edge_grid = _Grid(cell_m)
        self.node_grid = _Grid(cell_m)
        for i, p in enumerate(self.xy):
            self.node_grid.insert(i, p, p)

    def heading(self, u: int, v: int) -> float:
        return heading_rad(*self.xy[u], *self.xy[v])

    def can_add(self, u: int, v: int) -> bool:
        full = max(len(self.heads[u]), len(self.heads[v])) >= 4
        return not full and v not in self.heads[u] and self._fits(u, v)

    def _fits(self, u: int, v: int) -> bool:
        pu, pv = self.xy[u], self.xy[v]
        if not MIN_PIPE_DIAMETERS * self.diameter_m <= math.dist(pu, pv) <= self.longest_m:
            return False
        for a, b in ((u, v), (v, u)):
            h = self.heading(a, b)
            for w, other in self.heads[a].items():
                if w != b and abs(wrap_rad(h - other)) < MIN_JUNCTION_ANGLE_RAD:
                    return False
        lo, hi = _box(pu, pv, self.clearance_m)
        for e in self.edge_grid.near(lo, hi):
            a, b = self.edges[e]
            if {a, b} & {u, v}:
                continue
            if segments_touch(pu, pv, self.xy[a], self.xy[b]):
                return False
        return all(
            point_segment_distance_m(self.xy[w], pu, pv) >= self.clearance_m
            for w in self.node_grid.near(lo, hi)
            if w not in (u, v)
        )

    def add(self, u: int, v: int) -> None:
        self.heads[u][v] = self.heading(u, v)
        self.heads[v][u] = self.heading(v, u)
        key = len(self.edges) and max(self.edges) + 1
        self.edges[key] = (u, v)
        self.edge_grid.insert(key, *_box(self.xy[u], self.xy[v], 0.0))

    def _drop(self, u: int, v: int) -> int:
        key = next(k for k, e in self.edges.items() if set(e) == {u, v})
        self.edge_grid.remove(key, *_box(self.xy[u], self.xy[v], 0.0))
        del self.heads[u][v], self.heads[v][u]
        return key

    def straight(self, i: int) -> bool:
        if len(self.heads[i]) != 2:
            return False
        h1, h2 = self.heads[i].values()
        return abs(wrap_rad(h1 - h2)) > _GEN_STRAIGHT_RAD

    def shorter_m(self, i: int) -> float:
        """Length of the shorter pipe at node ``i``."""
        return min(math.dist(self.xy[i], self.xy[w]) for w in self.heads[i])

    def push(self, i: int, offset_m: float) -> bool:
        """Move node ``i`` (two pipes) sideways by ``offset_m`` if every rule still holds."""
        (a, b), old = list(self.heads[i]), self.xy[i]
        pa, pb = self.xy[a], self.xy[b]
        length = math.dist(pa, pb)
        nx, ny = -(pb[1] - pa[1]) / length, (pb[0] - pa[0]) / length
        new = (round(old[0] + offset_m * nx, 3), round(old[1] + offset_m * ny, 3))
        keys = [self._drop(i, a), self._drop(i, b)]
        self.node_grid.remove(i, old, old)
        self.xy[i] = new
        self.node_grid.insert(i, new, new)
        ok = self._clear_of_pipes(i) and self._fits(i, a) and self._fits(i, b)
        if ok:
            self.heads[i][a] = self.heading(i, a)
            self.heads[a][i] = self.heading(a, i)
            ok = self._fits(i, b)
            del self.heads[i][a], self.heads[a][i]
        if not ok:
            self.node_grid.remove(i, new, new)
            self.xy[i] = old
            self.node_grid.insert(i, old, old)
        for key, nbr in zip(keys, (a, b), strict=True):
            del self.edges[key]
            self.add(i, nbr)
        return ok and not self.straight(i)

    def _clear_of_pipes(self, i: int) -> bool:
        p = self.xy[i]
        lo, hi = _box(p, p, self.clearance_m)
        for e in self.edge_grid.near(lo, hi):
            a, b = self.edges[e]
            near = i not in (a, b)
            if near and point_segment_distance_m(p, self.xy[a], self.xy[b]) < self.clearance_m:
                return False
        return True


@dataclass
class _Repair:
    """What the local repairs of one draw share."""

    builder: _TownBuilder
    rng: np.random.Generator
    field: _Field
    gap_m: float
    entry: int = -1


def _reattach(fix: _Repair) -> bool:
    """Move every node the tree could not reach (hemmed in by pipes that pass it) to a
    free spot one district spacing from a reached node with room for a pipe, as a dead end;
    whether every node is then reached."""
    builder = fix.builder
    n = len(builder.xy)
    comp = _components(builder)
    main = max(set(comp), key=lambda c: (comp.count(c), -c))
    stranded = [i for i in range(n) if comp[i] != main]
    for i in stranded:
        for w in list(builder.heads[i]):
            del builder.edges[builder._drop(i, w)]
    for i in stranded:
        hosts = [h for h in range(n) if comp[h] == main and len(builder.heads[h]) < 4]
        if not _stub(fix, i, hosts):
            return False
        comp[i] = main
    return True


def _splice(fix: _Repair, i: int) -> bool:
    """Take straight node ``i`` out of its pipe (its two neighbours joined directly)
    and put it back as a dead end elsewhere; whether that fits (else nothing changes)."""
    builder, entry = fix.builder, fix.entry
    a, b = list(builder.heads[i])
    if entry in (a, b):
        return False
    saved = [builder._drop(i, a), builder._drop(i, b)]
    here = builder.xy[i]
    builder.node_grid.remove(i, here, here)
    joined = builder.can_add(a, b)
    builder.node_grid.insert(i, here, here)
    if joined:
        for key in saved:
            del builder.edges[key]
        builder.add(a, b)
        hosts = [h for h in range(len(builder.xy)) if h != i and len(builder.heads[h]) < 4]
        if _stub(fix, i, hosts):
            return True
        del builder.edges[builder._drop(a, b)]
    else:
        for key in saved:
            del builder.edges[key]
    builder.add(i, a)
    builder.add(i, b)
    return False


def _lend_leaf(fix: _Repair, i: int) -> bool:
    """Give straight node ``i`` a third pipe: a dead end taken from elsewhere (whose
    old corner does not go straight on without it) and put beside ``i``; whether
    one fitted (else nothing changes)."""
    builder, rng, entry = fix.builder, fix.rng, fix.entry
    leaves = [
        w
        for w in range(len(builder.xy))
        if len(builder.heads[w]) == 1 and w not in (entry, i) and w not in builder.heads[i]
    ]
    for leaf in (leaves[int(k)] for k in rng.permutation(len(leaves))[:64]):
        (host,) = builder.heads[leaf]
        key = builder._drop(leaf, host)
        if not builder.straight(host) and _stub(fix, leaf, [i]):
            del builder.edges[key]
            return True
        del builder.edges[key]
        builder.add(leaf, host)
    return False


def _components(builder: _TownBuilder) -> list[int]:
    comp = list(range(len(builder.xy)))
    for start in range(len(builder.xy)):
        if comp[start] != start:
            continue
        stack = [start]
        while stack:
            for w in builder.heads[stack.pop()]:
                if comp[w] != start:
                    comp[w] = start
                    stack.append(w)
    return comp


def _stub(fix: _Repair, i: int, hosts: list[int]) -> bool:
    """Move node ``i`` (no pipes) to a free spot one district spacing from one of
    ``hosts`` and join them; whether a spot fitted (else ``i`` stays where it was)."""
    builder, rng, gap_m = fix.builder, fix.rng, fix.gap_m
    old = builder.xy[i]
    builder.node_grid.remove(i, old, old)
    for h in (hosts[int(k)] for k in rng.permutation(len(hosts))[:256]):
        turn = float(rng.uniform(0.0, 2.0 * math.pi))
        spacing_m = fix.field.at(builder.xy[h])
        for k in range(12):
            angle = turn + k * math.pi / 6.0
            hx, hy = builder.xy[h]
            spot = (
                round(hx + spacing_m * math.cos(angle), 3),
                round(hy + spacing_m * math.sin(angle), 3),
            )
            lo, hi = _box(spot, spot, gap_m)
            if any(math.dist(spot, builder.xy[w]) < gap_m for w in builder.node_grid.near(lo, hi)):
                continue
            builder.xy[i] = spot
            builder.node_grid.insert(i, spot, spot)
            if builder._clear_of_pipes(i) and builder.can_add(h, i):
                builder.add(h, i)
                if not builder.straight(h):
                    return True
                del builder.edges[builder._drop(h, i)]
            builder.node_grid.remove(i, spot, spot)
    builder.xy[i] = old
    builder.node_grid.insert(i, old, old)
    return False


def _unstraighten(fix: _Repair, i: int, free: list[tuple[int, int]], loops: bool) -> bool:
    """Make straight node ``i`` turn: a loop pipe, a push sideways, a splice elsewhere
    or a dead end lent to it; whether one worked."""
    builder = fix.builder
    extra = next((e for e in free if i in e and builder.can_add(*e)), None)
    if extra is not None and loops:
        builder.add(*extra)
        return True
    return (
        any(builder.push(i, k * builder.shorter_m(i)) for k in _PUSHES)
        or _splice(fix, i)
        or _lend_leaf(fix, i)
    )


def _try_town(
    n: int, rng: np.random.Generator, spacing_m: float, loops: bool, diameter_m: float
) -> Network | None:
    """One draw of a town layout; ``None`` when it fails a requirement after repair."""
    field = _Field(n, rng, spacing_m)
    pts = _scatter(n, rng, field, diameter_m)
    candidates = [] if pts is None else _candidate_edges(pts)
    if pts is None or not candidates:
        return None
    order = [candidates[int(i)] for i in rng.permutation(len(candidates))]
    builder = _TownBuilder(pts, diameter_m, 2.0 * field.dense_m, _LONGEST * spacing_m)
    fix = _Repair(builder, rng, field, min_gap_m(field.dense_m, diameter_m))
    spare = grow_tree(builder, order, n)
    if len(builder.edges) != n - 1 and not _reattach(fix):
        return None
    leaves = [i for i in range(n) if len(builder.heads[i]) == 1]
    entry = leaves[int(rng.integers(len(leaves)))]
    fix.entry = entry
    free = [(u, v) for u, v in spare if entry not in (u, v)]
    if loops:
        target, added = int(rng.integers(n // 8, n // 4 + 1)), 0
        for u, v in free:
            if added == target:
                break
            if builder.can_add(u, v):
                builder.add(u, v)
                added += 1
    for _ in range(_STRAIGHT_PASSES):
        straight = [i for i in range(n) if builder.straight(i)]
        if not straight:
            break
        for i in straight:
            if builder.straight(i) and not _unstraighten(fix, i, free, loops):
                return None
    if any(builder.straight(i) for i in range(n)):
        return None
    return labelled(builder.xy, [e for _, e in sorted(builder.edges.items())], entry, diameter_m)


def town_network(spec: str, n: int, seed: int, spacing_m: float, loops: bool) -> Network:
    """An ``n``-node town layout drawn from ``seed``, pipes 1 to 20 times ``spacing_m``
    long, with loops if ``loops``; ``spec`` names it in the error when no draw succeeds."""
    return first_draw(spec, seed, _MAX_ATTEMPTS, _try_town, n, spacing_m, loops)
