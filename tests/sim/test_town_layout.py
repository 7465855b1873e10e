"""Town-scale networks: ``random:N`` above 100 nodes, ``grid:30x30``, and the size limit."""

from __future__ import annotations

import hashlib
import math
import subprocess
import sys
import time
from collections import Counter

import networkx as nx
import pytest

from pipemap.errors import SimError
from pipemap.sim import town_layout
from pipemap.sim.network import MAX_NODES, Network, build_network
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


def test_town_networks_are_drawn_in_a_fresh_process_the_same() -> None:
    code = (
        "from pipemap.sim.network import build_network;"
        "n = build_network('random:400', seed=9);"
        "print(repr([(x.label, x.x_m, x.y_m) for x in n.nodes]), [str(p) for p in n.pipes])"
    )
    outs = {
        subprocess.run(
            [sys.executable, "-c", code], capture_output=True, text=True, check=True
        ).stdout
        for _ in range(2)
    }
    assert len(outs) == 1


def test_above_100_nodes_the_town_generator_draws() -> None:
    assert TOWN_ABOVE == 100
    net = build_network("random:101", seed=0)
    rng_net = town_layout.town_network("random:101", 101, 0, 1.0, loops=True)
    assert _digest(net) == _digest(rng_net)


def test_grid_30x30_builds() -> None:
    net = build_network("grid:30x30")
    assert len(net.nodes) == 901
    assert len(net.pipes) == 2 * 30 * 29 + 1


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
