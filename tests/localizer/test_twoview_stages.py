"""The two-view check's speed-ups keep its answers: the Hamming matcher gives
OpenCV's pairs, and the staged match (an early gate on every eighth keypoint, then
a gate after every fourth) gives the one-stage fit wherever it goes on, and stops
early where it does not."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace
from typing import Any

import cv2
import numpy as np
import pytest

from pipemap.localizer import keymatch, stages, twoview
from pipemap.localizer.epipolar import _turned
from pipemap.localizer.fastmatch import FastMatcher
from pipemap.localizer.keymatch import _ratio_matches, _words
from pipemap.localizer.twoview import TwoViewConfig, fit_two_view, sweep_features
from tests.conftest import PaperSet


def _opencv_ratio_matches(
    a: np.ndarray, b: np.ndarray, ratio: float
) -> tuple[np.ndarray, np.ndarray]:
    """The pairs OpenCV's brute-force matcher and Lowe's test give (what
    ``_ratio_matches`` replaced)."""
    pairs = cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(b, a, k=2)
    good = [p[0] for p in pairs if len(p) == 2 and p[0].distance < ratio * p[1].distance]
    return (
        np.array([g.trainIdx for g in good], dtype=np.int64),
        np.array([g.queryIdx for g in good], dtype=np.int64),
    )


@pytest.mark.parametrize("seed", range(6))
def test_hamming_matcher_gives_opencvs_pairs(seed: int) -> None:
    """Half of ``b`` are noisy copies of ``a``'s descriptors (some exact, so that
    the nearest ties with a duplicate in ``a``), half unrelated."""
    rng = np.random.default_rng(seed)
    a = rng.integers(0, 256, (int(rng.integers(2, 500)), 32), dtype=np.uint8)
    a[1::7] = a[::7][: len(a[1::7])]  # duplicates: a tie for nearest fails the test
    copies = a[rng.integers(0, len(a), 120)].copy()
    flips = (rng.random(copies.shape) < 0.04) * rng.integers(1, 256, copies.shape)
    b = np.concatenate([copies ^ flips.astype(np.uint8), rng.integers(0, 256, (80, 32), np.uint8)])
    for ratio in (0.7, 0.8, 0.9):
        ia, ib = _ratio_matches(a, b, ratio)
        ja, jb = _opencv_ratio_matches(a, b, ratio)
        assert len(ia) > 0
        assert np.array_equal(ia, ja) and np.array_equal(ib, jb)
        ka, kb = _ratio_matches(a, b, ratio, _words(a))  # the words made by the caller
        assert np.array_equal(ka, ja) and np.array_equal(kb, jb)


def test_hamming_distances_up_to_all_256_bits() -> None:
    """Distances are counted two words to a byte (at most 128 each) before the
    sum: a descriptor's complement is 256 away, never 0."""
    rng = np.random.default_rng(9)
    a = rng.integers(0, 256, (40, 32), dtype=np.uint8)
    b = np.concatenate([~a[:10], a[10:20]])  # complements first, then copies
    ia, ib = _ratio_matches(a, b, 0.99)
    ja, jb = _opencv_ratio_matches(a, b, 0.99)
    assert np.array_equal(ia, ja) and np.array_equal(ib, jb)
    copies = ib >= 10
    assert np.array_equal(ia[copies], ib[copies])  # a copy's nearest is its original
    words_b = np.ascontiguousarray(b[:1]).view(np.uint64)
    assert sum(int(w).bit_count() for w in (words_b ^ _words(a)[:, :1].T)[0]) == 256


def test_hamming_matcher_needs_two_to_compare() -> None:
    one = np.zeros((1, 32), np.uint8)
    assert len(_ratio_matches(one, one, 0.8)[0]) == 0


def _paper_features(paper_sets: dict[str, PaperSet], name: str) -> twoview.SweepFeatures:
    return sweep_features(paper_sets[name].images)


@pytest.fixture(scope="module")
def features(paper_sets: dict[str, PaperSet]) -> dict[str, twoview.SweepFeatures]:
    names = ["1", "1_noise", "2_noise", "2_active", "3", "3_noise", "4", "10"]
    return {n: _paper_features(paper_sets, n) for n in names}


def _guess(paper_sets: dict[str, PaperSet], query: str, known: str) -> float:
    matcher = FastMatcher()
    matcher.add(matcher.prepare(paper_sets[known].images))
    return matcher.match(matcher.prepare(paper_sets[query].images))[0].rotation_rad


@pytest.mark.parametrize("with_guess", [True, False])
def test_two_stages_give_the_one_stage_fit(
    paper_sets: dict[str, PaperSet],
    features: dict[str, twoview.SweepFeatures],
    with_guess: bool,
) -> None:
    """Same junction, from other entries: the fit after the gate is the fit of one
    stage to the last bit (same matches in the same order, so the same search)."""
    one_stage = TwoViewConfig(gate_every=1, min_inliers=48)
    two_stage = TwoViewConfig(min_inliers=48)
    assert two_stage.gate_every == 4
    for q, k in [("1", "1_noise"), ("1_noise", "2_active"), ("3_noise", "1")]:
        guess = _guess(paper_sets, q, k) if with_guess else None
        one = fit_two_view(features[q], features[k], one_stage, guess)
        two = fit_two_view(features[q], features[k], two_stage, guess)
        assert one is not None and one.inliers >= 48
        assert two == one


def test_the_early_gate_stops_a_different_junction_after_an_eighth(
    seen: list[int], features: dict[str, twoview.SweepFeatures]
) -> None:
    """Different junctions: only every eighth keypoint of the known sweep is matched
    (every fourth without the early gate, every one in one stage), and the answer
    is the one-stage answer (no fit)."""
    config = TwoViewConfig(min_inliers=48)
    for q, k in itertools.permutations(["1", "4", "10"], 2):
        seen.clear()
        assert fit_two_view(features[q], features[k], config, None) is None
        assert sum(seen) == len(range(0, len(features[k]), 8))
        seen.clear()
        assert fit_two_view(features[q], features[k], replace(config, early_gate_share=0.0)) is None
        assert sum(seen) == len(range(0, len(features[k]), 4))
        seen.clear()
        assert fit_two_view(features[q], features[k], replace(config, gate_every=1)) is None
        assert sum(seen) == len(features[k])


@pytest.mark.parametrize("with_guess", [True, False])
def test_the_early_gate_keeps_every_fit_it_lets_through(
    paper_sets: dict[str, PaperSet],
    features: dict[str, twoview.SweepFeatures],
    with_guess: bool,
) -> None:
    """Same junction: the first stage matched in two halves gives the fit of one
    first stage to the last bit, and the lamp's second fit of a pair, through the
    match cache, too."""
    config = TwoViewConfig(min_inliers=48)
    without = replace(config, early_gate_share=0.0)
    for q, k in [("1", "1_noise"), ("2_noise", "2_active"), ("3_noise", "1")]:
        guess = _guess(paper_sets, q, k) if with_guess else None
        fit = fit_two_view(features[q], features[k], config, guess)
        assert fit is not None and fit == fit_two_view(features[q], features[k], without, guess)
        cache = keymatch.MatchCache(features[q])
        fit_two_view(features[q], features[k], config, 1.0, cache)  # a first fit elsewhere
        assert fit_two_view(features[q], features[k], config, guess, cache) == fit


@pytest.mark.parametrize(
    ("early", "matched", "grids"), [(0.9, 4, 0), (0.9, 5, 1), (0.0, 7, 0), (0.0, 8, 1)]
)
def test_fewer_matches_than_a_gate_asks_cost_no_grid(
    monkeypatch: pytest.MonkeyPatch,
    features: dict[str, twoview.SweepFeatures],
    early: float,
    matched: int,
    grids: int,
) -> None:
    """A pair of keypoints counts once in a cell of the coarse grid at most: with
    fewer matches than a gate asks (the early gate's 5, the first quarter's 8) the
    fit stops without counting; with as many the grid decides (here: a count of 4,
    so it stops too)."""
    counted: list[int] = []

    def few(
        query: object, known: object, ratio: float, overlap: object, only: np.ndarray, *rest: object
    ) -> tuple[np.ndarray, np.ndarray]:
        picked = np.flatnonzero(only)[:matched]
        return picked, picked

    def coarse(*args: Any) -> tuple[np.ndarray, np.ndarray, list[float]]:
        counted.append(len(args[2][0]))
        return np.array([[4]]), np.zeros(1), [0.0]

    monkeypatch.setattr(stages, "_matches", few)
    monkeypatch.setattr(stages, "_coarse", coarse)
    known = features["4"]
    config = TwoViewConfig(min_inliers=48, early_gate_share=early)
    assert fit_two_view(features["1"], known, config) is None
    assert counted == [matched] * grids


def test_no_early_gate_below_three(
    seen: list[int], features: dict[str, twoview.SweepFeatures]
) -> None:
    """The map's own junction is asked 24 inliers: an early gate of 2 (0.9 x 24 / 8)
    would stop nothing, so the first quarter is matched in one call, and the
    quarter's gate of 4 (0.7 x 24 / 4) is the first."""
    fit_two_view(features["1"], features["4"], TwoViewConfig(min_inliers=24), None)
    assert seen[0] == len(range(0, len(features["4"]), 4))
    seen.clear()
    fit_two_view(features["1"], features["4"], TwoViewConfig(min_inliers=27), None)
    assert seen[0] == len(range(0, len(features["4"]), 8))  # 0.9 x 27 / 8: 3


def test_no_gate_below_three(seen: list[int], features: dict[str, twoview.SweepFeatures]) -> None:
    """The plain fit's 12 inliers would make a first gate of 2 (0.7 x 12 / 4): one
    stage then, so a weak fit (the rotation of a revisit without the check) is never
    cut short. Any two matches fit some motion: such a gate would stop nothing."""
    fit_two_view(features["1"], features["4"], TwoViewConfig(), None)
    assert seen == [len(features["4"])]


def test_a_first_gate_of_three_is_kept(
    seen: list[int], features: dict[str, twoview.SweepFeatures]
) -> None:
    """20 inliers make a first gate of 3 (0.7 x 20 / 4): the first stage matches a
    quarter of the known keypoints."""
    fit_two_view(features["1"], features["4"], TwoViewConfig(min_inliers=20), None)
    assert seen[0] == len(range(0, len(features["4"]), 4))


@pytest.mark.parametrize(
    ("counts", "eighths_run"), [([4], 1), ([5, 7], 2), ([5, 8, 15], 4), ([5, 8, 16, 24], 6)]
)
def test_each_stage_asks_for_its_share(
    monkeypatch: pytest.MonkeyPatch,
    seen: list[int],
    features: dict[str, twoview.SweepFeatures],
    counts: list[int],
    eighths_run: int,
) -> None:
    """After the first eighth of the known keypoints the matches must reach 0.9 of
    an eighth of the 48 inliers on the coarse grid (5), after stage s of 4 then 0.7
    of s quarters (8, 16, 25): the fit stops at the first gate whose count falls
    short. Each count is one short of its gate (and the quarters' pass the gate of
    the old share, 0.5: 6, 12, 18)."""
    given = iter(counts)

    def coarse(*args: object) -> tuple[np.ndarray, np.ndarray, list[float]]:
        return np.array([[next(given)]]), np.zeros(1), [0.0]

    monkeypatch.setattr(stages, "_coarse", coarse)
    known = features["4"]
    assert fit_two_view(features["1"], known, TwoViewConfig(min_inliers=48)) is None
    assert sum(seen) == sum(len(range(s, len(known), 8)) for s in (0, 4, 1, 5, 2, 6)[:eighths_run])


def test_a_count_past_every_gate_is_not_counted_again(
    monkeypatch: pytest.MonkeyPatch, features: dict[str, twoview.SweepFeatures]
) -> None:
    """A count never falls as matches are added: when the first quarter already
    passes the last gate (25 of 48), the later gates cost no grid, only the fit.
    (The early gate's count is not taken for the quarter's: the grid the fit's
    search starts from must be the quarter's, as without the early gate.)"""
    calls: list[int] = []
    real = stages._coarse

    def counting(*args: Any) -> tuple[np.ndarray, np.ndarray, list[float]]:
        calls.append(len(args[2][0]))
        return real(*args)

    monkeypatch.setattr(stages, "_coarse", counting)
    fit = fit_two_view(features["1"], features["1_noise"], TwoViewConfig(min_inliers=48))
    assert fit is not None
    assert len(calls) == 2  # the early gate's, the first quarter's; then the search
    assert calls[0] < calls[1] < fit.matches


@pytest.fixture
def searched(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """How many rotations each coarse grid counted (the gate's, then the search's)."""
    counts: list[int] = []
    real = stages._grid_counts

    def counting(a: np.ndarray, b: np.ndarray, rotations: np.ndarray, *args: Any) -> np.ndarray:
        counts.append(len(rotations))
        return real(a, b, rotations, *args)

    monkeypatch.setattr(stages, "_grid_counts", counting)
    return counts


@pytest.mark.parametrize("with_guess", [True, False])
def test_a_clear_peak_of_the_gate_is_searched_around_only(
    paper_sets: dict[str, PaperSet],
    features: dict[str, twoview.SweepFeatures],
    searched: list[int],
    with_guess: bool,
) -> None:
    """Same junction from the same entry: the gate's quarter alone fits with the 48
    inliers asked (86 to 163), so the search on every match counts only the
    rotations within ten steps of its peak, and finds the start (and so the fit) of
    the search everywhere."""
    local = TwoViewConfig(min_inliers=48)
    everywhere = replace(local, local_steps=0)
    for q, k in [("1", "1_noise"), ("2_noise", "2_active"), ("3_noise", "3")]:
        guess = _guess(paper_sets, q, k) if with_guess else None
        searched.clear()
        near = fit_two_view(features[q], features[k], local, guess)
        whole = local.rotation_steps * (2 if with_guess else 1)
        assert searched[:2] == [whole, whole]  # the early gate's and the quarter's
        assert len(searched) == 3 and 0 < searched[2] <= 2 * (2 * local.local_steps + 1)
        searched.clear()
        assert fit_two_view(features[q], features[k], everywhere, guess) == near
        assert searched == [whole, whole, whole]
        assert near is not None and near.inliers >= 48


@pytest.mark.parametrize(("most", "rotations"), [(47, 121), (48, 21)])
def test_a_peak_short_of_the_fit_is_searched_everywhere(
    monkeypatch: pytest.MonkeyPatch,
    features: dict[str, twoview.SweepFeatures],
    searched: list[int],
    most: int,
    rotations: int,
) -> None:
    """A gate count below what the whole fit needs may be a peak of chance: the
    search on every match then counts every rotation."""
    real = stages._coarse

    def capped(*args: Any) -> tuple[np.ndarray, np.ndarray, list[float]]:
        counts, rots, centres = real(*args)
        return np.minimum(counts, most), rots, centres

    monkeypatch.setattr(stages, "_coarse", capped)
    fit_two_view(features["1"], features["1_noise"], TwoViewConfig(min_inliers=48))
    assert searched[-1] == rotations


def test_the_search_around_the_peak_wraps_at_half_a_turn(
    features: dict[str, twoview.SweepFeatures],
) -> None:
    """Turned so that the rotation lies near half a turn, the azimuth peak and the
    guess may fall either side of pi: a rotation and the same one a turn apart are
    both near the gate's peak, and the fit is still the search everywhere's."""
    query, known = features["1"], features["1_noise"]
    local = TwoViewConfig(min_inliers=48)
    base = fit_two_view(query, known, local)
    assert base is not None
    for offset in np.linspace(-0.3, 0.3, 13):
        turn = math.pi - base.rotation_rad + offset
        turned = replace(
            query,
            bearings=_turned(query.bearings, turn),
            image_azimuth_rad=query.image_azimuth_rad + turn,
        )
        for guess in (math.pi + offset - 0.2, math.pi + offset, math.pi + offset + 0.2):
            near = fit_two_view(turned, known, local, guess)
            assert near == fit_two_view(turned, known, replace(local, local_steps=0), guess)
