"""Tests of :mod:`localizer.localizer`: known or new, the map, the two-view check and
the junction the map expects, on synthetic image sets (no files; active vision and
ports have files of their own).

A junction is a smooth random panorama (blurred noise, one seed per junction); its
image set is N=6 views cut from it at equal steps, each view wider than the step so
that neighbours overlap, like the paper's camera sweep.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer.fastmatch import FastConfig, FastMatcher
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.localizer import (
    DEFAULT_THRESHOLD,
    PAPER,
    Decision,
    Localizer,
    LocalizerConfig,
    best_candidate,
)
from pipemap.localizer.similarity import SetMatch, wrap_angle_rad
from pipemap.localizer.twoview import TwoViewFit
from tests.localizer.junctions import (
    CORNER_EXITS,
    FOV_RAD,
    PI,
    ROWS,
    STEP_PX,
    STEP_RAD,
    STRICT,
    TEE_EXITS,
    WIDTH,
    FakeProbes,
    N,
    junction,
    strict_with,
    views,
)

# --- LocalizerConfig ----------------------------------------------------------------------


def test_config_defaults_are_the_papers_but_three_rules() -> None:
    config = LocalizerConfig()
    assert config.threshold == DEFAULT_THRESHOLD == 0.36
    assert config.active_vision is True
    assert config.probe_distance_m == 0.03
    assert config.fast == FastConfig()
    # pipemap's own rules, which PAPER turns off.
    assert (config.distinct_consecutive, config.two_view, config.verify) == (True, True, True)
    assert (PAPER.distinct_consecutive, PAPER.two_view, PAPER.verify) == (False, False, False)
    assert PAPER.threshold == config.threshold


def test_verify_needs_two_view() -> None:
    with pytest.raises(LocalizerError, match="two_view"):
        LocalizerConfig(two_view=False, verify=True)
    with pytest.raises(LocalizerError, match="verify_inliers"):
        LocalizerConfig(verify_inliers=0)


@pytest.mark.parametrize("threshold", [2.0, 1.0001, -1.0001, -5.0, math.nan], ids=str)
def test_config_threshold_out_of_range_raises(threshold: float) -> None:
    with pytest.raises(LocalizerError, match="threshold"):
        LocalizerConfig(threshold=threshold)


@pytest.mark.parametrize("threshold", [-1.0, 0.0, 1.0])
def test_config_threshold_bounds_are_accepted(threshold: float) -> None:
    assert LocalizerConfig(threshold=threshold).threshold == threshold


@pytest.mark.parametrize("distance", [-0.01, math.inf, math.nan], ids=str)
def test_config_bad_probe_distance_raises(distance: float) -> None:
    with pytest.raises(LocalizerError, match="probe distance"):
        LocalizerConfig(probe_distance_m=distance)


# --- the synthetic data itself --------------------------------------------------------------


def test_synthetic_sets_have_the_expected_geometry() -> None:
    s = junction(0)
    assert (s.count, s.height, s.width, s.kept_rows) == (N, ROWS, WIDTH, 64)
    # Consecutive views overlap by WIDTH - STEP_PX columns, cyclically.
    images = s.images
    for j in range(N):
        np.testing.assert_array_equal(
            images[j, :, STEP_PX:], images[(j + 1) % N, :, : WIDTH - STEP_PX]
        )
    assert not np.allclose(junction(0).images, junction(1).images)


# --- localize: known / new and the map ------------------------------------------------------


def test_first_visit_is_new_node_zero() -> None:
    loc = Localizer()
    d = loc.localize(junction(0))
    assert isinstance(d, Decision)
    assert d.node == 0
    assert d.known is False
    assert d.candidate is None
    assert d.margin is None
    assert d.similarity == 0.0
    assert d.match is None
    assert d.probes == ()
    assert loc.known_count == 1
    assert loc.map.visits == (0,)


def test_first_visit_requests_no_probe() -> None:
    probes = FakeProbes(default=junction(0))
    d = Localizer(LocalizerConfig(threshold=STRICT)).localize(junction(0), probes)
    assert probes.requests == []
    assert d.node == 0


def test_second_different_junction_is_new() -> None:
    loc = Localizer(PAPER)
    loc.localize(junction(0))
    d = loc.localize(junction(1))
    assert d.node == 1
    assert d.known is False
    assert d.candidate == 0
    assert d.margin is None  # only one known junction
    assert d.similarity < DEFAULT_THRESHOLD
    assert loc.known_count == 2


def test_revisit_is_known() -> None:
    loc = Localizer(PAPER)
    loc.localize(junction(0))
    loc.localize(junction(1))
    d = loc.localize(junction(0))
    assert d.known is True
    assert d.node == 0
    assert d.candidate == 0
    assert d.similarity > 0.9
    assert d.match is not None
    assert d.match.similarity == d.similarity
    assert d.match.image_shift == 0
    assert abs(d.match.rotation_rad) < 1e-3
    assert d.margin is not None and d.margin > 0.4
    assert loc.known_count == 2  # nothing added


@pytest.mark.parametrize("roll", [1, 2, 3, 5])
def test_revisit_with_rotated_sweep_is_known(roll: int) -> None:
    loc = Localizer()
    loc.localize(junction(0))
    loc.localize(junction(1))
    d = loc.localize(junction(0, roll=roll))
    assert d.known is True
    assert d.node == 0
    assert d.similarity > 0.9
    assert d.match is not None
    # Query image j is image j - roll of the known set: offset -roll.
    assert d.match.image_shift == (-roll) % N
    expected = -roll * STEP_RAD
    assert abs(wrap_angle_rad(d.match.rotation_rad - expected)) < 1e-3
    assert abs(wrap_angle_rad(d.match.rotation_pinhole_rad - expected)) < 1e-3


def test_revisit_with_shifted_view_estimates_rotation() -> None:
    loc = Localizer()
    loc.localize(junction(0))
    query = ImageSet(views(0, start_px=40), fov_rad=FOV_RAD)
    m = loc.compare(query)[0]
    assert m.image_shift == 0
    assert m.pixel_shift == pytest.approx(40.0, abs=0.5)
    assert m.rotation_rad == pytest.approx(40.0 * FOV_RAD / WIDTH, abs=0.01)


def test_map_gets_the_right_edges() -> None:
    loc = Localizer()
    sequence = [0, 1, 0, 2, 0, 2, 1]  # junction seeds in visit order
    nodes = [loc.localize(junction(seed)).node for seed in sequence]
    assert nodes == [0, 1, 0, 2, 0, 2, 1]
    assert loc.map.visits == tuple(nodes)
    assert loc.map.node_count == 3
    assert [(e.u, e.v, e.label) for e in loc.map.edges()] == [(0, 1, 1), (0, 2, 2), (2, 1, 3)]


def test_tree_exploration_builds_the_tree() -> None:
    # 0.6 sits far from both exact revisits (1.0) and other junctions (< 0.45).
    loc = Localizer(LocalizerConfig(threshold=0.6))
    seeds = [10, 11, 12, 11, 13, 14, 13, 15, 13, 16, 13, 11, 10]  # S A B A C D C E C F C A S
    decisions = [loc.localize(junction(seed)) for seed in seeds]
    assert [d.node for d in decisions] == [0, 1, 2, 1, 3, 4, 3, 5, 3, 6, 3, 1, 0]
    assert [d.known for d in decisions] == [
        False,
        False,
        False,
        True,
        False,
        False,
        True,
        False,
        True,
        False,
        True,
        True,
        True,
    ]
    assert [(e.u, e.v) for e in loc.map.edges()] == [(0, 1), (1, 2), (1, 3), (3, 4), (3, 5), (3, 6)]


def test_unseen_junctions_are_new_under_the_papers_threshold() -> None:
    # Eight different junctions, none seen twice: every visit must be new. Against the
    # full-resolution reference (localizer.similarity.reference_match) every pair
    # scores about 0.2, far below the paper's 0.36. A decision must not rest on a
    # screening-only match (SetMatch.refined False): the screen is the cascade's
    # cheap, upward-biased ranking stage, not Algorithm 2's similarity.
    loc = Localizer()
    decisions = [loc.localize(junction(seed)) for seed in range(20, 28)]
    relied_on_screen = [
        (i, d.candidate, round(d.similarity, 3))
        for i, d in enumerate(decisions)
        if d.match is not None and not d.match.refined
    ]
    wrongly_known = [
        (i, d.node, round(d.similarity, 3)) for i, d in enumerate(decisions) if d.known
    ]
    assert wrongly_known == [], "unseen junctions decided known (visit, node, similarity)"
    assert [d.node for d in decisions] == list(range(8))
    assert relied_on_screen == [], "decisions taken on unrefined screening similarities"


# --- consecutive visits are different junctions ---------------------------------------


def test_a_visit_is_never_the_junction_it_came_from() -> None:
    # The same sweep twice in a row: the paper's rules merge them, pipemap's default
    # cannot (the robot drove a pipe between the sweeps), and has nothing else to try.
    paper = Localizer(PAPER)
    paper.localize(junction(0))
    assert paper.localize(junction(0)).known
    loc = Localizer()
    loc.localize(junction(0))
    d = loc.localize(junction(0))
    assert (d.node, d.known, d.candidate, d.similarity, d.match) == (1, False, None, 0.0, None)
    assert loc.map.visits == (0, 1)


def test_the_previous_junction_gives_way_to_the_next_best() -> None:
    loc = Localizer()
    for seed in (0, 1):
        loc.localize(junction(seed))
    d = loc.localize(junction(1, noise=0.5, noise_seed=3))  # looks like 1, came from 1
    assert d.candidate == 0 and not d.known and d.node == 2
    assert d.similarity < 0.5
    assert d.match is not None and d.match.refined
    assert d.margin is None  # one junction competed


def test_the_rule_leaves_true_revisits_alone() -> None:
    loc = Localizer()
    nodes = [loc.localize(junction(seed)).node for seed in (0, 1, 0, 2, 0, 2, 1)]
    assert nodes == [0, 1, 0, 2, 0, 2, 1]


def test_the_excluded_junction_is_screened_but_not_refined() -> None:
    matcher = FastMatcher(FastConfig())
    for seed in (0, 1, 2):
        matcher.add(matcher.prepare(junction(seed)))
    prepared = matcher.prepare(junction(2))
    matches = matcher.match(prepared, exclude=2)
    assert matches[2].refined is False
    assert matches[0].refined and matches[1].refined
    assert best_candidate(matches, exclude=2)[0] in (0, 1)


# --- compare ---------------------------------------------------------------------------


def test_compare_with_no_junctions_is_empty() -> None:
    assert Localizer().compare(junction(0)) == []


def test_compare_returns_one_match_per_known_junction() -> None:
    loc = Localizer()
    for seed in (0, 1, 2):
        loc.localize(junction(seed))
    matches = loc.compare(junction(1))
    assert len(matches) == 3
    assert all(isinstance(m, SetMatch) for m in matches)
    assert matches[1].similarity > 0.99
    assert matches[0].similarity < 0.5
    assert matches[2].similarity < 0.5
    # Comparing records nothing.
    assert loc.known_count == 3
    assert loc.map.visits == (0, 1, 2)


def test_compare_agrees_with_localize() -> None:
    loc = strict_with(0, 1)
    query = junction(0, noise=1.0)
    matches = loc.compare(query)
    best, sim, margin = best_candidate(matches)
    d = loc.localize(query)
    assert (d.candidate, d.similarity, d.margin) == (best, sim, margin)
    assert d.match == matches[0]


# --- errors -----------------------------------------------------------------------------


def test_query_of_different_image_size_raises() -> None:
    loc = Localizer()
    loc.localize(junction(0))
    narrow = ImageSet(junction(0).images[:, :, :160], fov_rad=FOV_RAD)
    with pytest.raises(LocalizerError):
        loc.localize(narrow)
    with pytest.raises(LocalizerError):
        loc.compare(narrow)
    fewer = ImageSet(junction(0).images[:5], fov_rad=FOV_RAD)
    with pytest.raises(LocalizerError):
        loc.localize(fewer)
    # The failed visits changed nothing.
    assert loc.known_count == 1
    assert loc.map.visits == (0,)


def test_query_with_different_kept_fraction_raises_localizer_error() -> None:
    # Same image shape, but a different crop: the sets are not comparable
    # (ImageSet.check_comparable says so); the localizer must say so too.
    loc = Localizer()
    loc.localize(junction(0))
    query = ImageSet(junction(0).images, fov_rad=FOV_RAD, keep_top_fraction=0.25)
    with pytest.raises(LocalizerError):
        loc.localize(query)


def test_query_with_different_field_of_view_raises_localizer_error() -> None:
    # A different field of view changes the meaning of the pixel shift in the
    # rotation estimate; ImageSet.check_comparable rejects such a pair.
    loc = Localizer()
    loc.localize(junction(0))
    query = ImageSet(junction(0).images, fov_rad=1.0)
    with pytest.raises(LocalizerError):
        loc.localize(query)


# --- The two-view check (pipemap's default decision) ----------------------------------------


def test_geometry_decides_not_the_threshold() -> None:
    """At threshold -1 every similarity passes; the two-view check still keeps three
    different junctions apart and recognises the revisit, with its rotation."""
    loc = Localizer(LocalizerConfig(threshold=-1.0))
    decisions = [loc.localize(junction(seed)) for seed in (0, 1, 2)]
    assert [d.known for d in decisions] == [False, False, False]
    assert decisions[2].candidate is not None and decisions[2].two_view is None
    again = loc.localize(junction(0, roll=2))
    assert again.known and again.node == 0
    assert again.two_view is not None and again.two_view.inliers >= 48
    assert again.rotation_rad == again.two_view.rotation_rad


def test_without_verify_the_threshold_decides() -> None:
    loc = Localizer(LocalizerConfig(threshold=-1.0, verify=False))
    decisions = [loc.localize(junction(seed)) for seed in (0, 1, 2)]
    assert decisions[2].known  # everything passes -1


def test_too_few_keypoints_leave_the_decision_to_the_threshold() -> None:
    """Sweeps of a few dozen pixels have too few keypoints to check: the threshold
    decides them, as in the paper."""
    tiny = [ImageSet(np.asarray(junction(s).images)[:, ::8, ::8]) for s in (0, 1, 2)]
    loc = Localizer(LocalizerConfig(threshold=-1.0))
    decisions = [loc.localize(t) for t in tiny]
    assert decisions[2].known and decisions[2].two_view is None


# --- the junction the map expects -------------------------------------------------------


def test_the_junction_the_map_expects_is_tried_first() -> None:
    # Junction 0 is a T, seen through noise; junction 2 a dead end that looks exactly
    # like junction 0 did without it. Only one candidate gets the two-view check.
    def walk(loc: Localizer) -> Decision:
        loc.localize(junction(0, noise=0.3), exits_rad=TEE_EXITS)
        assert loc.expected_node() is None  # the run's first junction
        loc.depart(PI / 2)  # port 1
        assert loc.expected_node() is None  # an untraversed pipe
        loc.localize(junction(1), exits_rad=CORNER_EXITS)
        loc.depart(PI / 2)
        assert not loc.localize(junction(0), exits_rad=(PI,)).known  # its exits say new
        loc.depart(PI)
        assert loc.localize(junction(1), exits_rad=(PI / 2, PI)).node == 1
        loc.depart(PI)  # back along the pipe from junction 0
        assert Localizer.expected_node(loc) == 0
        return loc.localize(junction(0), exits_rad=TEE_EXITS)

    d = walk(Localizer(LocalizerConfig(verify_candidates=1)))
    assert d.known and d.node == 0

    # Without the map's prior the most similar junction is 2, a dead end: its one
    # port cannot line up with a T's three exits, so it takes no candidate's place,
    # and junction 0 is the one candidate tried.
    class NoPrior(Localizer):
        def expected_node(self) -> int | None:
            return None

    tried: list[tuple[int, int]] = []  # (visit, junction fitted)
    no_prior = NoPrior(LocalizerConfig(verify_candidates=1))
    real = no_prior._fit

    def fit(node: int, *args: Any) -> TwoViewFit | None:
        tried.append((len(no_prior.map.visit_records), node))
        return real(node, *args)

    no_prior._fit = fit  # type: ignore[method-assign]
    d = walk(no_prior)
    assert d.known and d.node == 0 and d.rejected == ()
    assert [node for visit, node in tried if visit == 4] == [0]


@pytest.mark.parametrize("expected_inliers, known", [(24, True), (48, False)])
def test_the_expected_junction_needs_fewer_inliers(
    monkeypatch: pytest.MonkeyPatch, expected_inliers: int, known: bool
) -> None:
    """Every fit is cut to 30 inliers: below ``verify_inliers`` (48), so only the
    junction the map expects can be recognised, and only under its own bar."""
    from pipemap.localizer import verify as module

    real = module.fit_two_view

    def thirty(query, known_features, config, guess=None, cache=None):  # type: ignore[no-untyped-def]
        fit = real(query, known_features, replace(config, min_inliers=12), guess, cache)
        return None if fit is None else replace(fit, inliers=30)

    monkeypatch.setattr(module, "fit_two_view", thirty)
    loc = Localizer(LocalizerConfig(expected_inliers=expected_inliers))
    loc.localize(junction(0), exits_rad=TEE_EXITS)
    loc.depart(PI / 2)  # port 1
    assert not loc.localize(junction(1), exits_rad=CORNER_EXITS).known
    loc.depart(PI)  # back along the pipe it came by: the map expects junction 0
    assert loc.expected_node() == 0
    d = loc.localize(junction(0), exits_rad=TEE_EXITS)
    assert d.known is known and (d.node == 0) is known
    if known:
        assert d.two_view is not None and d.two_view.inliers == 30


def test_expected_inliers_is_validated() -> None:
    with pytest.raises(LocalizerError, match="expected_inliers"):
        LocalizerConfig(expected_inliers=0)
