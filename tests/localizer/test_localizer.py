"""Tests of :mod:`localizer.localizer`: Algorithm 1 (decide), Algorithm 3 (active
vision) and the localizer's map, on synthetic image sets (no files).

A junction is a smooth random panorama (blurred noise, one seed per junction); its
image set is N=6 views cut from it at equal steps, each view wider than the step so
that neighbours overlap, like the paper's camera sweep.
"""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import cv2
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
    ProbeKind,
    ProbeRequest,
    best_candidate,
    probe_plan,
)
from pipemap.localizer.similarity import SetMatch, wrap_angle_rad

ROWS = 128
COLS = 960
N = 6
STEP_PX = COLS // N  # 160
WIDTH = 192
#: The view's field of view matches the panorama's geometry: 192 of 960 columns.
FOV_RAD = 2.0 * math.pi * WIDTH / COLS
STEP_RAD = 2.0 * math.pi / N

#: High enough that only a (near) exact revisit is known: a set with added noise is
#: weak (about 0.96: the paper's quarter scale averages the noise of 16 pixels) and
#: other junctions are far below (under 0.45).
STRICT = 0.985

PAPER_ORDER = [ProbeKind.ROTATE, ProbeKind.FORWARD, ProbeKind.BACK, ProbeKind.LEFT, ProbeKind.RIGHT]


@functools.cache
def _panorama(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    noise = rng.normal(size=(ROWS, COLS)).astype(np.float32)
    smooth = cv2.GaussianBlur(noise, (0, 0), 3.0)
    out = 128.0 + 40.0 * smooth / float(smooth.std())
    out.setflags(write=False)
    return out


def _views(seed: int, start_px: int = 0) -> np.ndarray:
    pano = _panorama(seed)
    starts = [start_px + j * STEP_PX for j in range(N)]
    return np.stack([pano[:, np.arange(s, s + WIDTH) % COLS] for s in starts])


def junction(seed: int, *, roll: int = 0, noise: float = 0.0, noise_seed: int = 99) -> ImageSet:
    """The image set of junction ``seed``; ``roll`` starts the sweep ``roll`` images
    later (a cyclic permutation), ``noise`` adds Gaussian noise of that many
    standard deviations of the images."""
    images = _views(seed)
    if noise:
        rng = np.random.default_rng(noise_seed)
        images = images + noise * float(images.std()) * rng.normal(size=images.shape)
    return ImageSet(np.roll(images, roll, axis=0), fov_rad=FOV_RAD)


class FakeProbes:
    """A :class:`ProbeSource` that records requests and answers from a table."""

    def __init__(
        self,
        answers: dict[ProbeKind, ImageSet | None] | None = None,
        default: ImageSet | None = None,
    ) -> None:
        self.answers = answers if answers is not None else {}
        self.default = default
        self.requests: list[ProbeRequest] = []

    def probe(self, request: ProbeRequest) -> ImageSet | None:
        self.requests.append(request)
        return self.answers.get(request.kind, self.default)

    @property
    def kinds(self) -> list[ProbeKind]:
        return [r.kind for r in self.requests]


def _strict_with(*seeds: int, **config: object) -> Localizer:
    # These tests exercise the paper's rules, under which every known junction competes
    # and the threshold decides.
    loc = Localizer(replace(PAPER, threshold=STRICT, **config))  # type: ignore[arg-type]
    for seed in seeds:
        assert not loc.localize(junction(seed)).known
    return loc


def _match(similarity: float) -> SetMatch:
    return SetMatch(
        similarity=similarity,
        image_shift=0,
        pixel_shift=0.0,
        rotation_rad=0.0,
        rotation_pinhole_rad=0.0,
    )


# --- decide (Algorithm 1) -------------------------------------------------------------


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
    from dataclasses import replace

    screened = replace(_match(0.9), refined=False)
    assert best_candidate([_match(0.4), screened, _match(0.3)]) == (0, 0.4, pytest.approx(0.1))
    # With no refined match at all, the screening scores are all there is.
    assert best_candidate([screened, replace(_match(0.2), refined=False)])[0] == 0


# --- probe_plan -------------------------------------------------------------------------


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
    query = ImageSet(_views(0, start_px=40), fov_rad=FOV_RAD)
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
    loc = _strict_with(0, 1)
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


def test_probe_of_different_size_raises() -> None:
    loc = _strict_with(0, 1)
    wrong = ImageSet(junction(0).images[:, :, :160], fov_rad=FOV_RAD)
    with pytest.raises(LocalizerError):
        loc.localize(junction(0, noise=1.0), FakeProbes(default=wrong))
    assert loc.known_count == 2


# --- active vision (Algorithm 3) --------------------------------------------------------


def test_strong_match_requests_no_probe() -> None:
    loc = _strict_with(0, 1)
    probes = FakeProbes(default=junction(1))
    d = loc.localize(junction(0, roll=2), probes)
    assert probes.requests == []
    assert d.probes == ()
    assert d.known is True
    assert d.node == 0


def test_weak_match_without_improvement_requests_all_five_in_order() -> None:
    loc = _strict_with(0, 1)
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
    loc = _strict_with(0, 1)
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
    loc = _strict_with(0, 1)
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
    loc = _strict_with(0, 1, 2)
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
    loc = _strict_with(0, 1)
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
    loc = _strict_with(0, 1)
    query = junction(0, noise=1.0)
    better = junction(0, noise=0.8, noise_seed=5)
    d = loc.localize(query, FakeProbes({ProbeKind.ROTATE: better}))
    assert d.node == 2 and not d.known
    matches = loc.compare(query)
    assert matches[2].similarity > 0.99
    again = loc.localize(query)
    assert again.known and again.node == 2


def test_missing_probes_are_counted_and_the_visit_is_still_decided() -> None:
    loc = _strict_with(0, 1)
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
    loc = _strict_with(0, 1)
    query = junction(2)
    probes = FakeProbes({ProbeKind.BACK: query, ProbeKind.RIGHT: query})
    d = loc.localize(query, probes)
    assert probes.kinds == PAPER_ORDER
    assert d.missing_probes == 3
    assert [p.similarity is None for p in d.probes] == [True, True, False, True, False]


def test_no_probe_source_means_no_active_vision() -> None:
    loc = _strict_with(0, 1)
    d = loc.localize(junction(0, noise=1.0), None)
    assert d.probes == ()
    assert d.known is False
    assert d.node == 2


def test_active_vision_off_requests_nothing() -> None:
    loc = _strict_with(0, 1, active_vision=False)
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
    loc = _strict_with(0, 1)
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
    loc = _strict_with(1, 0)  # the weak candidate is node 1 now
    query = junction(0, roll=3, noise=1.0)
    best = loc.compare(query)[1]
    probes = FakeProbes()
    d = loc.localize(query, probes)
    assert d.candidate == 1
    assert probes.requests[0].yaw_rad == best.rotation_pinhole_rad
    assert abs(best.rotation_pinhole_rad) == pytest.approx(math.pi, abs=0.02)


@pytest.mark.parametrize("distance", [0.05, 0.0, 0.25])
def test_request_distance_follows_config(distance: float) -> None:
    loc = _strict_with(0, 1, probe_distance_m=distance)
    probes = FakeProbes()
    loc.localize(junction(2), probes)
    moves = {r.kind: (r.forward_m, r.left_m, r.yaw_rad) for r in probes.requests}
    assert moves[ProbeKind.FORWARD] == (distance, 0.0, 0.0)
    assert moves[ProbeKind.BACK] == (-distance, 0.0, 0.0)
    assert moves[ProbeKind.LEFT] == (0.0, distance, 0.0)
    assert moves[ProbeKind.RIGHT] == (0.0, -distance, 0.0)
    assert moves[ProbeKind.ROTATE][:2] == (0.0, 0.0)


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


# --- ports: the robot's exits and the known junction's pipes --------------------------

PI = math.pi
#: A T seen from its stem (behind), and a corner.
TEE_EXITS = (PI, PI / 2, -PI / 2)
CORNER_EXITS = (PI, PI / 2)


def test_exits_give_a_new_junction_its_ports() -> None:
    loc = Localizer()
    d = loc.localize(junction(0), exits_rad=(0.0 - 0.01, -PI / 2, PI))
    assert d.exits_rad == (-0.01, -PI / 2, PI)
    assert d.exit_ports == (1, 2, 0)  # ahead, right, behind: behind is port 0, then clockwise
    assert d.arrival_port is None  # the run's first visit came by no pipe
    assert loc.map.ports(0) == pytest.approx((PI, -0.01, -PI / 2))
    assert loc.depart(-PI / 2 + 0.05) == 2
    assert loc.map.visit_records[0].departure_port == 2


def test_a_revisit_whose_exits_agree_is_known_and_its_exits_get_ports() -> None:
    loc = Localizer()
    loc.localize(junction(0), exits_rad=TEE_EXITS)
    loc.depart(PI / 2)
    loc.localize(junction(1), exits_rad=CORNER_EXITS)
    loc.depart(PI / 2)
    # The same sweep (rotation 0), its exits measured a little off and in another order.
    d = loc.localize(junction(0), exits_rad=(-PI / 2 + 0.05, PI - 0.04, PI / 2))
    assert d.known and d.node == 0
    assert d.exit_ports == (2, 0, 1)
    assert d.arrival_port == 0
    assert d.port_residual_rad == pytest.approx(0.05, abs=1e-6)
    assert d.rejected == ()
    edges = loc.map.edges()
    assert [(e.u, e.u_port, e.v, e.v_port) for e in edges] == [(0, 1, 1, 0), (1, 1, 0, 0)]


@pytest.mark.parametrize("config", [LocalizerConfig(), PAPER, replace(PAPER, port_check=True)])
def test_a_match_whose_exits_disagree_is_passed_over(config: LocalizerConfig) -> None:
    loc = Localizer(config)
    loc.localize(junction(0), exits_rad=TEE_EXITS)
    loc.localize(junction(1), exits_rad=CORNER_EXITS)
    d = loc.localize(junction(0), exits_rad=CORNER_EXITS)  # the images say T, the scan a corner
    if not config.port_check:
        assert d.known and d.node == 0 and d.exit_ports is None
        return
    assert not d.known and d.node == 2
    assert d.rejected == ((0, "2 exits where the junction has 3 ports"),)
    assert d.exit_ports == (0, 1)


def test_the_next_candidate_whose_exits_agree_is_taken() -> None:
    loc = Localizer(replace(PAPER, port_check=True))
    loc.localize(junction(0), exits_rad=TEE_EXITS)
    # A look-alike corner (the same images, a little noise): a new junction by its exits.
    first = loc.localize(junction(0, noise=0.1), exits_rad=CORNER_EXITS)
    assert not first.known and first.rejected[0][0] == 0
    d = loc.localize(junction(0), exits_rad=CORNER_EXITS)
    assert d.known and d.node == 1
    assert [c for c, _ in d.rejected] == [0]
    assert d.similarity < 1.0 - 1e-6 < loc.compare(junction(0))[0].similarity


def test_turned_exits_agree_through_the_measured_rotation() -> None:
    loc = Localizer()
    loc.localize(junction(0), exits_rad=TEE_EXITS)
    loc.localize(junction(1), exits_rad=CORNER_EXITS)
    # The sweep started one image later: the robot heads one step (60 degrees) further
    # left (the rotation to the first visit's heading is -60 degrees), so every pipe
    # is 60 degrees further right of it.
    turned = tuple(math.remainder(e - STEP_RAD, 2 * PI) for e in TEE_EXITS)
    d = loc.localize(junction(0, roll=1), exits_rad=turned)
    assert d.known and d.exit_ports == (0, 1, 2)


def test_port_tolerance_is_validated() -> None:
    with pytest.raises(LocalizerError, match="port tolerance"):
        LocalizerConfig(port_tolerance_rad=0.0)


def test_without_exits_nothing_changes() -> None:
    loc = Localizer()
    d = loc.localize(junction(0))
    assert d.exits_rad is None and d.exit_ports is None and d.arrival_port is None
    assert loc.depart(0.0) is None
    assert loc.map.ports(0) is None


def test_a_new_traversal_may_start_at_the_last_junction() -> None:
    loc = Localizer()
    loc.localize(junction(0))
    loc.localize(junction(1))
    loc.new_traversal()
    d = loc.localize(junction(1))  # left out right after junction 1, allowed now
    assert d.known and d.node == 1
    assert len(loc.map.edges()) == 1


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

    # Without the map's prior: the most similar junction, 2, is the only one tried,
    # and its exits do not fit.
    class NoPrior(Localizer):
        def expected_node(self) -> int | None:
            return None

    d = walk(NoPrior(LocalizerConfig(verify_candidates=1)))
    assert not d.known and [c for c, _ in d.rejected] == [2]


@pytest.mark.parametrize("expected_inliers, known", [(24, True), (48, False)])
def test_the_expected_junction_needs_fewer_inliers(
    monkeypatch: pytest.MonkeyPatch, expected_inliers: int, known: bool
) -> None:
    """Every fit is cut to 30 inliers: below ``verify_inliers`` (48), so only the
    junction the map expects can be recognised, and only under its own bar."""
    from pipemap.localizer import localizer as module

    real = module.fit_two_view

    def thirty(query, known_features, config, guess=None):  # type: ignore[no-untyped-def]
        fit = real(query, known_features, replace(config, min_inliers=12), guess)
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
