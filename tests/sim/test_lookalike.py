"""Junctions that look alike (``--alike``): which ones share a look, and that the
world draws them alike (small renders)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipemap.errors import SimError
from pipemap.sim import CameraSpec, World, build_network
from pipemap.sim.lookalike import TYPE_TOLERANCE_RAD, LookAlike, choose_looks

SMALL = CameraSpec(resolution_px=64)
EVEN = CameraSpec(resolution_px=64, lamp_strength=0.0)


def _gaps(network, label: str) -> list[float]:  # type: ignore[no-untyped-def]
    heads = sorted(network.pipe_headings(label).values())
    if len(heads) == 1:
        return [2 * math.pi]
    return [(heads[(i + 1) % len(heads)] - h) % (2 * math.pi) for i, h in enumerate(heads)]


def _same_type(network, a: str, b: str, tolerance: float) -> bool:  # type: ignore[no-untyped-def]
    ga, gb = _gaps(network, a), _gaps(network, b)
    n = len(ga)
    return len(gb) == n and any(
        max(abs(gb[(i + s) % n] - ga[i]) for i in range(n)) <= tolerance for s in range(n)
    )


def test_alike_zero_shares_nothing_and_a_bad_fraction_is_refused() -> None:
    net = build_network("random:16", seed=3)
    assert choose_looks(net, 0.0, 3) == LookAlike(0.0)
    for bad in (-0.1, 1.5, math.nan):
        with pytest.raises(SimError, match="alike"):
            choose_looks(net, bad, 3)


def test_at_one_every_junction_of_a_type_wears_one_look() -> None:
    net = build_network("grid:3x3")
    groups = choose_looks(net, 1.0, 0).groups()
    # Five tees (r0c0 has the entry's pipe below it), three further corners; the cross
    # and the entry have no other of their type.
    assert sorted(sorted(g) for g in groups) == [
        ["r0c0", "r0c1", "r1c0", "r1c2", "r2c1"],
        ["r0c2", "r2c0", "r2c2"],
    ]
    # The paper's network: the entry and the four dead ends are alike, its tee and its
    # cross are the only ones of their kind.
    assert [sorted(g) for g in choose_looks(build_network("paper"), 1.0, 0).groups()] == [
        ["B", "D", "E", "F", "S"]
    ]


@pytest.mark.parametrize("seed", [3, 11])
def test_a_shared_look_is_worn_by_junctions_of_one_type_chosen_by_the_seed(seed: int) -> None:
    net = build_network("random:20", seed=seed)
    full = choose_looks(net, 1.0, seed)
    half = choose_looks(net, 0.5, seed)
    assert choose_looks(net, 0.5, seed) == half  # the same seed, the same choice
    for looks in (full, half):
        for group in looks.groups():
            for other in group[1:]:
                assert _same_type(net, group[0], other, 2 * TYPE_TOLERANCE_RAD)
    wearers = sum(len(g) - 1 for g in full.groups())
    assert wearers >= 4
    assert sum(len(g) - 1 for g in half.groups()) == math.floor(0.5 * wearers + 0.5)
    # Each wearer's ports map one to one onto its look's.
    for label, look in full.looks.items():
        assert sorted(look.ports.values()) == list(range(net.degree(label)))


def test_another_seed_chooses_other_looks() -> None:
    net = build_network("random:20", seed=5)
    choices = {tuple(map(tuple, choose_looks(net, 0.5, s).groups())) for s in range(6)}
    assert len(choices) > 1


def _sweep(world: World, label: str, start_rad: float) -> list[np.ndarray]:
    n = world.network.node(label)
    eye = (n.x_m + 1e-4, n.y_m + 1e-4, world.network.diameter_m / 2)
    return [
        world.render(eye, start_rad + k * math.pi / 3, EVEN).astype(np.float64) for k in range(6)
    ]


def _ncc(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    return float((a * b).sum() / math.sqrt((a * a).sum() * (b * b).sum()))


def _aligned_start(net, looks: LookAlike, label: str) -> float:  # type: ignore[no-untyped-def]
    """The heading of the pipe that wears the look's first port."""
    look = looks.looks[label]
    return min(net.pipe_headings(look.look).values()) + look.turn_rad


def test_junctions_that_share_a_look_are_drawn_alike_turned_with_their_ports() -> None:
    # random:16 seed 3 at alike 1: a corner look worn by junctions whose pipes point
    # other ways than its own, so the chamber and the pipes must turn with them.
    net = build_network("random:16", seed=3)
    looks = choose_looks(net, 1.0, 3)
    corners = next(g for g in looks.groups() if net.degree(g[0]) >= 2)
    name = corners[0]
    other = max(corners[1:], key=lambda m: abs(math.remainder(looks.looks[m].turn_rad, math.tau)))
    assert abs(math.remainder(looks.looks[other].turn_rad, math.tau)) > 0.3
    own = LookAlike(0.0)
    with World(net, seed=3, texture_px=128, looks=looks) as alike:
        a = _sweep(alike, name, _aligned_start(net, looks, name))
        b = _sweep(alike, other, _aligned_start(net, looks, other))
    with World(net, seed=3, texture_px=128, looks=own) as apart:
        c = _sweep(apart, name, _aligned_start(net, looks, name))
        d = _sweep(apart, other, _aligned_start(net, looks, other))
    same = [_ncc(x, y) for x, y in zip(a, b, strict=True)]
    differ = [_ncc(x, y) for x, y in zip(c, d, strict=True)]
    # Evenly lit, the walls' texture decides. Their pipes meet at angles up to twice
    # the type's tolerance apart, so the views are alike, not equal; a chamber left
    # unturned drops one view under 0.3.
    assert min(same) > 0.7 and float(np.mean(same)) > 0.8, same
    assert float(np.mean(differ)) < float(np.mean(same)) - 0.2, (same, differ)


def test_alike_zero_draws_the_world_as_without_the_setting() -> None:
    net = build_network("paper")
    at_s = (0.0001, 0.0001, 0.05)  # the entry S, looking up its pipe to A
    with World(net, seed=3, texture_px=64) as plain:
        one = plain.render(at_s, math.pi / 2, SMALL)
    with World(net, seed=3, texture_px=64, looks=choose_looks(net, 0.0, 3)) as zero:
        assert np.array_equal(one, zero.render(at_s, math.pi / 2, SMALL))
    with World(net, seed=3, texture_px=64, looks=choose_looks(net, 1.0, 3)) as alike:
        assert not np.array_equal(one, alike.render(at_s, math.pi / 2, SMALL))
