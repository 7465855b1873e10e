"""Town-scale networks: ``random:N`` and ``grid:RxC`` above 100 nodes, and the size limit."""

from __future__ import annotations

import hashlib
import math
import statistics
import subprocess
import sys
import time
from collections import Counter

import networkx as nx
import pytest

from pipemap.errors import SimError
from pipemap.sim import town_layout
from pipemap.sim.network import MAX_NODES, Network, build_network
from pipemap.sim.planar import segments_touch
from pipemap.sim.random_layout import _GEN_STRAIGHT_RAD
from pipemap.sim.town_layout import TOWN_ABOVE


def _digest(net: Network) -> str:
    h = hashlib.sha256()
    for n in net.nodes:
        h.update(f"{n.label} {n.x_m!r} {n.y_m!r};".encode())
    for p in net.pipes:
        h.update(f"{p.a}-{p.b};".encode())
    return h.hexdigest()[:16]


@pytest.mark.parametrize(
    ("spec", "seed", "digest"),
    [
        ("random:8", 0, "72b6166d0129622d"),
        ("random:24", 35, "9bc03984ed22816c"),
        ("tree:12", 3, "3730c34a5ecf9497"),
        ("grid:5x5", 0, "80cdef0b6684bb6f"),
        ("grid:3x3", 1, "976357255caa6879"),
        ("grid:10x10", 0, "ac34da82454d64fc"),
        ("grid:10x10", 7, "ac34da82454d64fc"),
        ("grid:2x50", 3, "ca1edc123e315752"),
        ("random:50", 40, "a7e4fa76c4eb8ab6"),
        ("tree:60", 7, "0e1c85cef2029415"),
        ("random:100", 0, "cb22588725769d77"),
    ],
)
def test_specs_up_to_100_nodes_draw_the_networks_they_always_drew(
    spec: str, seed: int, digest: str
) -> None:
    # Digests of the networks as drawn before town layouts existed: the stored logs,
    # tests and benchmarks name these specs, and their logs must stay byte-identical.
    assert _digest(build_network(spec, seed=seed)) == digest


def _check_town(net: Network, n: int) -> None:
    assert len(net.nodes) == n
    degrees = Counter(net.degree(label) for label in net.labels)
    assert set(degrees) <= {1, 2, 3, 4}
    assert degrees[1] >= n // 20, "a town has dead ends"
    assert nx.is_connected(net.to_networkx())
    for label in net.labels:
        if net.degree(label) == 2:
            h1, h2 = net.pipe_headings(label).values()
            turn = abs(math.remainder(h1 - h2, 2.0 * math.pi))
            assert turn <= _GEN_STRAIGHT_RAD, f"{label} goes nearly straight on"


@pytest.mark.parametrize(("n", "seed"), [(200, 75), (1000, 0), (1000, 1)])
def test_random_town_networks_have_loops_dead_ends_and_turning_corners(n: int, seed: int) -> None:
    net = build_network(f"random:{n}", seed=seed)  # a Network: planar and buildable
    _check_town(net, n)
    loops = len(net.pipes) - (n - 1)
    assert n // 8 <= loops, "a town's mains close into loops"


@pytest.mark.parametrize(("n", "seed"), [(300, 5), (1000, 0)])
def test_town_tree_is_a_tree(n: int, seed: int) -> None:
    net = build_network(f"tree:{n}", seed=seed)
    _check_town(net, n)
    assert len(net.pipes) == n - 1


def _lengths(net: Network) -> list[float]:
    return [net.length_m(p.a, p.b) for p in net.pipes]


@pytest.mark.parametrize(
    ("spec", "seed"), [("random:200", 75), ("random:1000", 1), ("tree:1000", 0)]
)
def test_town_pipes_spread_over_1_to_20_m(spec: str, seed: int) -> None:
    lengths = _lengths(build_network(spec, seed=seed))
    assert 1.0 <= min(lengths) < 1.5, "dense districts keep pipes of about a metre"
    assert 15.0 < max(lengths) <= 20.0, "sparse districts have mains of up to 20 m"
    share = sum(length > 5.0 for length in lengths) / len(lengths)
    assert 0.1 < share < 0.5, f"{share:.2f} of the pipes over 5 m: short pipes stay the most"


def test_town_pipe_lengths_follow_the_spacing() -> None:
    lengths = _lengths(build_network("random:300", seed=2, spacing_m=0.5))
    assert min(lengths) >= 0.5
    assert max(lengths) <= 10.0
    assert max(lengths) > 5.0


def test_town_networks_are_seeded() -> None:
    a = build_network("random:300", seed=4)
    assert _digest(build_network("random:300", seed=4)) == _digest(a)
    assert _digest(build_network("random:300", seed=5)) != _digest(a)


def _drawn_in_fresh_processes(spec: str, seed: int) -> set[str]:
    """What two fresh interpreters print of ``spec`` drawn from ``seed``."""
    code = (
        "from pipemap.sim.network import build_network;"
        f"n = build_network({spec!r}, seed={seed});"
        "print(repr([(x.label, x.x_m, x.y_m) for x in n.nodes]), [str(p) for p in n.pipes])"
    )
    return {
        subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, check=True
        ).stdout
        for _ in range(2)
    }


def test_town_networks_are_drawn_in_a_fresh_process_the_same() -> None:
    assert len(_drawn_in_fresh_processes("random:400", 9)) == 1


def test_above_100_nodes_the_town_generator_draws() -> None:
    assert TOWN_ABOVE == 100
    net = build_network("random:101", seed=0)
    rng_net = town_layout.town_network("random:101", 101, 0, 1.0, loops=True)
    assert _digest(net) == _digest(rng_net)


def _crossing_pairs(net: Network) -> list[tuple[str, str]]:
    """Pairs of pipes without a common node that share a point, checked pair by pair."""
    xy = {n.label: (n.x_m, n.y_m) for n in net.nodes}
    found = []
    for i, p in enumerate(net.pipes):
        for q in net.pipes[i + 1 :]:
            if {p.a, p.b} & {q.a, q.b}:
                continue
            if segments_touch(xy[p.a], xy[p.b], xy[q.a], xy[q.b]):
                found.append((str(p), str(q)))
    return found


@pytest.mark.parametrize(
    ("spec", "seed"), [("grid:30x30", 0), ("grid:20x50", 3), ("grid:11x11", 1)]
)
def test_town_grids_have_dead_ends_corners_and_loops(spec: str, seed: int) -> None:
    net = build_network(spec, seed=seed)
    rows, cols = (int(k) for k in spec.removeprefix("grid:").split("x"))
    n = rows * cols + 1
    assert net.labels == ("S", *(f"r{r}c{c}" for r in range(rows) for c in range(cols)))
    _check_town(net, n)
    degrees = Counter(net.degree(label) for label in net.labels)
    assert degrees[1] >= n // 10, "dead ends beyond the entry"
    assert degrees[4] < n // 5, "most crossings of a town grid are not full crosses"
    assert n // 8 <= len(net.pipes) - (n - 1) <= n // 4, "a town's mains close into loops"
    assert list(net.pipe_headings("S")) == ["r0c0"]
    s, r0c0 = net.node("S"), net.node("r0c0")
    assert (s.x_m, s.y_m) == (r0c0.x_m, round(r0c0.y_m - 1.0, 3)), "the entry below r0c0"


def _bent_streets(net: Network, rows: int, cols: int) -> int:
    """Streets whose nodes stray further across than jitter alone moves them (at most
    a tenth of the gap beside them, end to end)."""
    along_rows = [[net.node(f"r{r}c{c}").y_m for c in range(cols)] for r in range(rows)]
    along_cols = [[net.node(f"r{r}c{c}").x_m for r in range(rows)] for c in range(cols)]
    count = 0
    for lines in (along_rows, along_cols):
        mid = [statistics.median(line) for line in lines]
        gaps = [b - a for a, b in zip(mid, mid[1:], strict=False)]
        for k, line in enumerate(lines):
            beside = min(gaps[max(k - 1, 0)], gaps[min(k, len(gaps) - 1)])
            count += max(line) - min(line) > 0.11 * beside
    return count


def test_town_grid_streets_bend_and_jitter_but_stay_apart() -> None:
    net = build_network("grid:30x30", seed=0)
    slopes = [
        abs(math.remainder(h, math.pi / 2.0))
        for label in net.labels
        for h in net.pipe_headings(label).values()
    ]
    assert 4 <= _bent_streets(net, 30, 30) <= 24, "a few of the 60 streets bend"
    assert sum(s > math.radians(0.5) for s in slopes) > len(slopes) // 2, "nodes are jittered"
    assert max(slopes) < math.radians(20.0), "streets bend slightly"
    assert _crossing_pairs(net) == [], "planar: no two pipes cross"


def test_town_grid_pipes_spread_over_1_to_20_m() -> None:
    for seed in (0, 1, 2):
        lengths = _lengths(build_network("grid:30x30", seed=seed))
        assert min(lengths) >= 0.99 and max(lengths) <= 20.0
        assert max(lengths) > 8.0, "sparse districts have long mains"
        assert sum(length < 2.0 for length in lengths) > len(lengths) // 20, "dense districts"
        assert 0.1 < sum(length > 5.0 for length in lengths) / len(lengths) < 0.6


def test_town_grid_spacing_scales_the_streets() -> None:
    double = _lengths(build_network("grid:30x30", seed=0, spacing_m=2.0))
    assert min(double) >= 2.0
    assert 16.0 < max(double) <= 40.0, "streets up to 12 spacings apart, bends included"


def test_town_grids_are_seeded() -> None:
    a = build_network("grid:20x20", seed=4)
    assert _digest(build_network("grid:20x20", seed=4)) == _digest(a)
    assert _digest(build_network("grid:20x20", seed=5)) != _digest(a)
    (fresh,) = _drawn_in_fresh_processes("grid:25x25", 9)
    here = build_network("grid:25x25", seed=9)
    assert fresh.startswith(repr([(x.label, x.x_m, x.y_m) for x in here.nodes]))


def test_grid_above_100_nodes_is_a_town_grid() -> None:
    lattice = build_network("grid:10x10", seed=3)
    assert {round(_lengths(lattice)[k], 6) for k in range(len(lattice.pipes))} == {1.0}
    assert len(build_network("grid:10x10").pipes) == 2 * 10 * 9 + 1
    town = build_network("grid:10x11", seed=3)
    assert len(town.pipes) < 2 * 10 * 11 - 21 + 1
    assert len(set(_lengths(town))) > 10


def test_grid_30x30_is_a_town_drawn_in_about_a_second() -> None:
    start = time.process_time()
    net = build_network("grid:30x30")
    assert time.process_time() - start < 5.0
    assert len(net.nodes) == 901
    assert nx.check_planarity(net.to_networkx())[0]
    assert 901 - 1 + 901 // 8 <= len(net.pipes) < 2 * 30 * 29 + 1


@pytest.mark.parametrize("spec", ["random:100000", "tree:5001", "grid:100x100", "grid:71x71"])
def test_specs_too_large_for_a_world_are_refused_at_once(spec: str) -> None:
    start = time.perf_counter()
    with pytest.raises(SimError, match=f"more than the {MAX_NODES}"):
        build_network(spec)
    assert time.perf_counter() - start < 0.5, "refused before anything is drawn"


def test_record_refuses_a_huge_spec_with_one_line(tmp_path) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "run.mcap"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "pipemap",
            "record",
            "--network",
            "random:100000",
            "-o",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert len(done.stderr.splitlines()) == 1
    assert done.stderr.startswith("pipemap: error: network spec 'random:100000': 100000 nodes")
    assert not out.exists()
