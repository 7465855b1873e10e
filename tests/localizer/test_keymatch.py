"""The match cache of :mod:`localizer.keymatch`: a second fit of one pair of sweeps
(the lamp's, at any rotation) gives the matches of comparing everything anew, and
compares each known keypoint with each query keypoint once."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from pipemap.localizer import Decision, Localizer, LocalizerConfig, keymatch
from pipemap.localizer import verify as verify_module
from pipemap.localizer.keymatch import MatchCache, _matches, overlapping_images
from pipemap.localizer.twoview import SweepFeatures, TwoViewConfig, fit_two_view, sweep_features
from tests.conftest import PaperSet


def _sweep(rng: np.random.Generator, per_image: list[int]) -> SweepFeatures:
    """Random descriptors, ``per_image[j]`` keypoints in image j; a third of them
    near copies of others (so that ratio tests pass and fail), bearings unused."""
    n = sum(per_image)
    descriptors = rng.integers(0, 256, (n, 32), dtype=np.uint8)
    image = np.repeat(np.arange(len(per_image)), per_image).astype(np.uint8)
    looks = -np.arange(len(per_image)) * 2.0 * math.pi / len(per_image)
    return SweepFeatures(np.zeros((n, 3)), descriptors, 0.01, image, looks, 1.4)


def _related(rng: np.random.Generator, a: SweepFeatures, per_image: list[int]) -> SweepFeatures:
    b = _sweep(rng, per_image)
    copies = rng.choice(len(a), size=min(len(a), len(b)) // 3, replace=False)
    flips = rng.random((len(copies), 32)) < 0.04
    b.descriptors[: len(copies)] = a.descriptors[copies] ^ (
        flips * rng.integers(1, 256, flips.shape)
    ).astype(np.uint8)
    # Look-alikes half a turn apart (images 0 and 3, never both in one overlap): two
    # query keypoints near one known one, so the test must fail once both are seen.
    twins = np.flatnonzero(a.image == 0)[:8]
    halfway = np.flatnonzero(a.image == 3)[:8]
    a.descriptors[halfway] = a.descriptors[twins] ^ np.uint8(1)
    b.descriptors[len(copies) : len(copies) + len(twins)] = a.descriptors[twins] ^ np.uint8(2)
    # An exact tie: two query keypoints at the same distance.
    a.descriptors[np.flatnonzero(a.image == 1)[0]] = a.descriptors[twins[-1]]
    return b


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("stages", [1, 4])
def test_a_cached_second_match_is_a_fresh_match(seed: int, stages: int) -> None:
    """Overlapping images first, then every image (and again the overlap): through
    one cache the very matches, in the very order, of matching each anew. Image 4
    of the query has one keypoint and image 5 none."""
    rng = np.random.default_rng(seed)
    a = _sweep(rng, [40, 35, 50, 30, 1, 0])
    b = _related(rng, a, [30, 45, 20, 40, 25, 35])
    overlap = overlapping_images(a, b, float(rng.uniform(-math.pi, math.pi)), 0.6)
    assert overlap is not None
    cache = MatchCache(a)
    part = np.arange(len(b)) % stages
    for step in (overlap, None, overlap, None):
        for stage in range(stages):
            only = None if stages == 1 else part == stage
            got = _matches(a, b, 0.8, step, only, cache)
            fresh = _matches(a, b, 0.8, step, only)
            assert len(fresh[0]) > 0
            assert all(np.array_equal(g, f) for g, f in zip(got, fresh, strict=True))


@pytest.fixture
def pairs_compared(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """How many (known, query) keypoint pairs each Hamming count took."""
    counts: list[int] = []
    real = keymatch._nearest_two

    def counting(words_a: np.ndarray, b: np.ndarray):  # type: ignore[no-untyped-def]
        counts.append(words_a.shape[1] * len(b))
        return real(words_a, b)

    monkeypatch.setattr(keymatch, "_nearest_two", counting)
    return counts


def test_the_second_fit_compares_only_what_the_first_did_not(
    paper_sets: dict[str, PaperSet], pairs_compared: list[int]
) -> None:
    """Two different junctions: the fit at a rotation and the fit at any rotation of
    the same pair, through one cache, compare every keypoint pair of the early
    gate's eighth exactly once; without the cache, the overlap's pairs twice. Both give
    what the fits give alone."""
    query, known = (sweep_features(paper_sets[n].images) for n in ("1", "4"))
    config = TwoViewConfig(min_inliers=48)
    cache = MatchCache(query)
    assert fit_two_view(query, known, config, 0.5, cache=cache) is None
    first = sum(pairs_compared)
    assert fit_two_view(query, known, config, None, cache=cache) is None
    eighth = len(range(0, len(known), 8))
    assert sum(pairs_compared) == eighth * len(query)
    assert 0 < first < eighth * len(query)
    pairs_compared.clear()
    assert fit_two_view(query, known, config, 0.5) is None
    assert fit_two_view(query, known, config, None) is None
    assert sum(pairs_compared) == eighth * len(query) + first


def test_a_cached_retry_finds_the_junction_a_fresh_one_does(
    paper_sets: dict[str, PaperSet],
) -> None:
    """The same junction, with a guess half a turn off: the fit at the guess fails
    and the fit at any rotation, through the cache, is the fresh fit."""
    query, known = (sweep_features(paper_sets[n].images) for n in ("1", "1_noise"))
    config = TwoViewConfig(min_inliers=48)
    cache = MatchCache(query)
    wrong = math.pi
    assert fit_two_view(query, known, config, wrong, cache=cache) is None
    retry = fit_two_view(query, known, config, None, cache=cache)
    assert retry is not None and retry.inliers >= 48
    assert retry == fit_two_view(query, known, config, None)


def test_under_a_lamp_the_localizer_retries_through_the_cache(
    paper_sets: dict[str, PaperSet], pairs_compared: list[int], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A new junction under the lamp: each candidate is fitted at the NCC's rotation,
    then at any rotation, and the second fit compares only what the first did not:
    the same decision as without the cache, for fewer keypoint pairs."""
    config = LocalizerConfig(lamp=True, active_vision=False, distinct_consecutive=False)

    def decide() -> tuple[Decision, int]:
        loc = Localizer(config)
        for name in ("4", "10"):
            loc.localize(paper_sets[name].images)
        pairs_compared.clear()
        return loc.localize(paper_sets["1"].images), sum(pairs_compared)

    cached, fewer = decide()
    monkeypatch.setattr(verify_module, "MatchCache", lambda query: None)
    fresh, more = decide()
    assert not cached.known and cached == fresh
    assert fewer < more


def test_a_cache_needs_the_image_of_each_keypoint() -> None:
    rng = np.random.default_rng(0)
    a = replace(_sweep(rng, [5, 5]), image=None)
    with pytest.raises(ValueError, match="image"):
        MatchCache(a)
