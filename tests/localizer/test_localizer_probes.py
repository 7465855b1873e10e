"""Tests of :class:`localizer.Localizer`'s active vision (Algorithm 3): which probes
it asks for, in which order, and how their sweeps decide, on synthetic junctions."""

from __future__ import annotations

import math

import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.localizer import (
    ProbeKind,
)
from pipemap.localizer.similarity import wrap_angle_rad
from tests.localizer.junctions import (
    FOV_RAD,
    PAPER_ORDER,
    STEP_RAD,
    STRICT,
    FakeProbes,
    junction,
    strict_with,
)


def test_probe_of_different_size_raises() -> None:
    loc = strict_with(0, 1)
    wrong = ImageSet(junction(0).images[:, :, :160], fov_rad=FOV_RAD)
    with pytest.raises(LocalizerError):
        loc.localize(junction(0, noise=1.0), FakeProbes(default=wrong))
    assert loc.known_count == 2


def test_strong_match_requests_no_probe() -> None:
    loc = strict_with(0, 1)
    probes = FakeProbes(default=junction(1))
    d = loc.localize(junction(0, roll=2), probes)
    assert probes.requests == []
    assert d.probes == ()
    assert d.known is True
    assert d.node == 0


def test_weak_match_without_improvement_requests_all_five_in_order() -> None:
    loc = strict_with(0, 1)
    query = junction(2)  # a new junction: weak against both
    probes = FakeProbes(default=query)  # every probe sees the same: no improvement
    d = loc.localize(query, probes)
    assert probes.kinds == PAPER_ORDER
    assert [p.request for p in d.probes] == probes.requests
    assert all(p.improved is False for p in d.probes)
    assert all(p.similarity == d.similarity for p in d.probes)
    assert d.similarity < STRICT
    assert d.known is False
    assert d.node == 2
    assert d.missing_probes == 0
    assert loc.known_count == 3


def test_probe_reaching_a_known_junction_stops_and_decides_known() -> None:
    loc = strict_with(0, 1)
    query = junction(0, noise=1.0)
    probes = FakeProbes({ProbeKind.ROTATE: query, ProbeKind.FORWARD: junction(0)}, default=query)
    before = loc.compare(query)[0].similarity
    assert 0.5 < before < STRICT
    d = loc.localize(query, probes)
    assert probes.kinds == [ProbeKind.ROTATE, ProbeKind.FORWARD]
    assert len(d.probes) == 2
    assert d.probes[0].improved is False
    assert d.probes[0].similarity == pytest.approx(before)
    assert d.probes[1].improved is True
    assert d.probes[1].similarity is not None and d.probes[1].similarity > 0.99
    assert d.known is True
    assert d.node == 0
    assert d.candidate == 0
    assert d.similarity == d.probes[1].similarity
    assert d.match is not None and d.match.similarity == d.similarity
    assert d.margin is not None and d.margin > 0.4
    assert loc.known_count == 2
    assert loc.map.visits == (0, 1, 0)


def test_a_probes_rotation_is_reported_from_the_visits_own_heading() -> None:
    # The rotate probe turns the robot by its yaw; the probe sweep's match gives the
    # rotation from the turned heading, so the decision adds the turn back.
    loc = strict_with(0, 1)
    query = junction(0, roll=2, noise=1.0)  # two camera steps off, and weak
    turned = junction(0)  # after turning by the estimate, lined up with the known sweep
    after_turn = loc.compare(turned)[0]
    probes = FakeProbes({ProbeKind.ROTATE: turned})
    d = loc.localize(query, probes)
    assert probes.kinds == [ProbeKind.ROTATE] and d.known and d.node == 0
    yaw = probes.requests[0].yaw_rad
    assert abs(yaw) > 0.1
    assert d.match is not None
    assert d.match.rotation_rad == pytest.approx(wrap_angle_rad(after_turn.rotation_rad + yaw))
    assert d.match.rotation_pinhole_rad == pytest.approx(
        wrap_angle_rad(after_turn.rotation_pinhole_rad + yaw)
    )


def test_probe_can_reveal_a_known_junction_for_a_new_looking_visit() -> None:
    loc = strict_with(0, 1, 2)
    query = junction(3)  # looks new: weak against all three
    probes = FakeProbes({ProbeKind.ROTATE: None, ProbeKind.FORWARD: junction(1)})
    d = loc.localize(query, probes)
    assert probes.kinds == [ProbeKind.ROTATE, ProbeKind.FORWARD]
    assert d.known is True
    assert d.node == 1
    assert d.candidate == 1
    assert d.similarity > 0.99
    assert d.missing_probes == 1
    assert loc.known_count == 3
    assert loc.map.visits == (0, 1, 2, 1)
    assert [(e.u, e.v) for e in loc.map.edges()] == [(0, 1), (1, 2)]


def test_improving_probe_below_threshold_stops_and_decides_new() -> None:
    loc = strict_with(0, 1)
    query = junction(0, noise=1.0)
    better = junction(0, noise=0.8, noise_seed=5)
    probes = FakeProbes({ProbeKind.FORWARD: better}, default=query)
    d = loc.localize(query, probes)
    assert probes.kinds == [ProbeKind.ROTATE, ProbeKind.FORWARD]
    assert d.probes[1].improved is True
    assert d.known is False
    assert d.node == 2
    assert d.candidate == 0
    assert d.probes[1].similarity == d.similarity
    assert loc.compare(query)[0].similarity < d.similarity < STRICT


def test_new_junction_stores_the_visits_own_sweep_not_the_probes() -> None:
    loc = strict_with(0, 1)
    query = junction(0, noise=1.0)
    better = junction(0, noise=0.8, noise_seed=5)
    d = loc.localize(query, FakeProbes({ProbeKind.ROTATE: better}))
    assert d.node == 2 and not d.known
    matches = loc.compare(query)
    assert matches[2].similarity > 0.99
    again = loc.localize(query)
    assert again.known and again.node == 2


def test_missing_probes_are_counted_and_the_visit_is_still_decided() -> None:
    loc = strict_with(0, 1)
    query = junction(0, noise=1.0)
    probes = FakeProbes()  # answers None to everything
    before = loc.compare(query)
    d = loc.localize(query, probes)
    assert probes.kinds == PAPER_ORDER
    assert d.missing_probes == 5
    assert all(p.similarity is None and p.improved is False for p in d.probes)
    assert d.known is False
    assert d.node == 2
    assert d.candidate == 0
    assert d.similarity == before[0].similarity
    assert d.match == before[0]
    assert loc.map.visits == (0, 1, 2)


def test_some_missing_probes() -> None:
    loc = strict_with(0, 1)
    query = junction(2)
    probes = FakeProbes({ProbeKind.BACK: query, ProbeKind.RIGHT: query})
    d = loc.localize(query, probes)
    assert probes.kinds == PAPER_ORDER
    assert d.missing_probes == 3
    assert [p.similarity is None for p in d.probes] == [True, True, False, True, False]


def test_no_probe_source_means_no_active_vision() -> None:
    loc = strict_with(0, 1)
    d = loc.localize(junction(0, noise=1.0), None)
    assert d.probes == ()
    assert d.known is False
    assert d.node == 2


def test_active_vision_off_requests_nothing() -> None:
    loc = strict_with(0, 1, active_vision=False)
    probes = FakeProbes(default=junction(0))  # would make it known
    d = loc.localize(junction(0, noise=1.0), probes)
    assert probes.requests == []
    assert d.probes == ()
    assert d.known is False
    assert d.node == 2


# The ROTATE request carries the best match's rotation estimate. The localizer uses
# pipemap's pinhole estimate (SetMatch.rotation_pinhole_rad), not the paper's linear
# rotation_rad; both agree closely on these sets, but the request is the pinhole one.
def test_rotate_request_uses_the_best_match_rotation() -> None:
    loc = strict_with(0, 1)
    query = junction(0, roll=2, noise=1.0)
    best = loc.compare(query)[0]
    assert best.similarity < STRICT
    assert best.rotation_rad == pytest.approx(-2.0 * STEP_RAD, abs=0.02)  # not trivially 0
    assert best.rotation_pinhole_rad == pytest.approx(best.rotation_rad, abs=0.02)
    probes = FakeProbes()
    d = loc.localize(query, probes)
    assert probes.requests[0].kind is ProbeKind.ROTATE
    assert probes.requests[0].yaw_rad == best.rotation_pinhole_rad
    assert d.match is not None
    assert d.match == best
    assert probes.requests[0].yaw_rad == d.match.rotation_pinhole_rad


def test_rotate_request_follows_the_best_candidate() -> None:
    loc = strict_with(1, 0)  # the weak candidate is node 1 now
    query = junction(0, roll=3, noise=1.0)
    best = loc.compare(query)[1]
    probes = FakeProbes()
    d = loc.localize(query, probes)
    assert d.candidate == 1
    assert probes.requests[0].yaw_rad == best.rotation_pinhole_rad
    assert abs(best.rotation_pinhole_rad) == pytest.approx(math.pi, abs=0.02)


@pytest.mark.parametrize("distance", [0.05, 0.0, 0.25])
def test_request_distance_follows_config(distance: float) -> None:
    loc = strict_with(0, 1, probe_distance_m=distance)
    probes = FakeProbes()
    loc.localize(junction(2), probes)
    moves = {r.kind: (r.forward_m, r.left_m, r.yaw_rad) for r in probes.requests}
    assert moves[ProbeKind.FORWARD] == (distance, 0.0, 0.0)
    assert moves[ProbeKind.BACK] == (-distance, 0.0, 0.0)
    assert moves[ProbeKind.LEFT] == (0.0, distance, 0.0)
    assert moves[ProbeKind.RIGHT] == (0.0, -distance, 0.0)
    assert moves[ProbeKind.ROTATE][:2] == (0.0, 0.0)
