"""Tests of :mod:`localizer.decision`: Algorithm 1's choice of the best candidate
and the paper's probe order."""

from __future__ import annotations

from dataclasses import replace

import pytest

from pipemap.localizer.localizer import (
    ProbeKind,
    ProbeRequest,
    best_candidate,
    probe_plan,
)
from pipemap.localizer.similarity import SetMatch
from tests.localizer.junctions import (
    PAPER_ORDER,
)


def _match(similarity: float) -> SetMatch:
    return SetMatch(
        similarity=similarity,
        image_shift=0,
        pixel_shift=0.0,
        rotation_rad=0.0,
        rotation_pinhole_rad=0.0,
    )


def test_decide_with_no_candidates() -> None:
    assert best_candidate([]) == (None, 0.0, None)


def test_decide_best_similarity_and_margin() -> None:
    best, sim, margin = best_candidate([_match(0.2), _match(0.7), _match(0.5)])
    assert best == 1
    assert sim == 0.7
    assert margin == pytest.approx(0.2)


def test_decide_margin_is_to_the_second_best_not_the_next() -> None:
    best, sim, margin = best_candidate([_match(0.6), _match(0.1), _match(0.9), _match(0.85)])
    assert (best, sim) == (2, 0.9)
    assert margin == pytest.approx(0.05)


def test_decide_ties_go_to_the_lowest_index() -> None:
    best, sim, margin = best_candidate([_match(0.1), _match(0.7), _match(0.7), _match(0.7)])
    assert best == 1
    assert sim == 0.7
    assert margin == 0.0


def test_decide_tie_at_index_zero() -> None:
    assert best_candidate([_match(0.5), _match(0.5)]) == (0, 0.5, 0.0)


def test_decide_one_candidate_has_no_margin() -> None:
    assert best_candidate([_match(0.42)]) == (0, 0.42, None)


def test_decide_negative_similarities() -> None:
    best, sim, margin = best_candidate([_match(-0.3), _match(-0.1)])
    assert (best, sim) == (1, -0.1)
    assert margin == pytest.approx(0.2)


def test_screening_only_matches_do_not_compete_with_refined_ones() -> None:

    screened = replace(_match(0.9), refined=False)
    assert best_candidate([_match(0.4), screened, _match(0.3)]) == (0, 0.4, pytest.approx(0.1))
    # With no refined match at all, the screening scores are all there is.
    assert best_candidate([screened, replace(_match(0.2), refined=False)])[0] == 0


def test_probe_plan_order_and_values() -> None:
    plan = probe_plan(0.7, 0.03)
    assert plan == (
        ProbeRequest(ProbeKind.ROTATE, yaw_rad=0.7),
        ProbeRequest(ProbeKind.FORWARD, forward_m=0.03),
        ProbeRequest(ProbeKind.BACK, forward_m=-0.03),
        ProbeRequest(ProbeKind.LEFT, left_m=0.03),
        ProbeRequest(ProbeKind.RIGHT, left_m=-0.03),
    )


def test_probe_plan_fields_are_exclusive() -> None:
    plan = probe_plan(-1.25, 0.1)
    assert [p.kind for p in plan] == PAPER_ORDER
    rotate, forward, back, left, right = plan
    assert (rotate.yaw_rad, rotate.forward_m, rotate.left_m) == (-1.25, 0.0, 0.0)
    for p in (forward, back, left, right):
        assert p.yaw_rad == 0.0
    assert (forward.forward_m, forward.left_m) == (0.1, 0.0)
    assert (back.forward_m, back.left_m) == (-0.1, 0.0)
    assert (left.forward_m, left.left_m) == (0.0, 0.1)
    assert (right.forward_m, right.left_m) == (0.0, -0.1)


def test_a_decision_describes_itself_in_one_line() -> None:
    """What ``pipemap -v`` prints: only what the decision holds, in a fixed order."""
    from pipemap.localizer.decision import Decision, ProbeOutcome
    from pipemap.localizer.twoview import TwoViewFit

    new = Decision(node=3, known=False, candidate=None, similarity=0.0, margin=None, match=None)
    assert new.describe() == "junction 3 new"
    asked = (
        ProbeOutcome(ProbeRequest(ProbeKind.ROTATE, yaw_rad=1.0), 0.31, False),
        ProbeOutcome(ProbeRequest(ProbeKind.FORWARD, forward_m=0.03), None, False),
    )
    known = Decision(
        node=1,
        known=True,
        candidate=1,
        similarity=0.5123,
        margin=0.25,
        match=_match(0.5123),
        probes=asked,
        two_view=TwoViewFit(rotation_rad=-1.5682, direction_rad=0.0, inliers=175, matches=300),
        rejected=((4, "exits are 0.51 rad off"),),
    )
    assert known.describe() == (
        "junction 1 known; best candidate 1 at 0.512, margin 0.250; "
        "two-view 175 inliers, turn -1.5682 rad; 2 probes asked, 1 answered; "
        "4 rejected: exits are 0.51 rad off"
    )
