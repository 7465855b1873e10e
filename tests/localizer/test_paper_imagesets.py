"""The localizer on the paper's own image sets, imagery nobody here rendered.

Ground truth comes from each set's recorded camera pose (``info.txt``): the same
junction when x, y are within 0.15 m, and the true relative rotation ``yaw_b - yaw_a``.
The reference values of every pair are stored in ``data/paper_reference.json``
(written by ``benchmarks/bench_localizer.py --write-reference``, minutes of work);
one test recomputes a few of them live so that the file cannot drift from the code.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pytest

from pipemap.localizer import (
    DEFAULT_THRESHOLD,
    FastMatcher,
    Localizer,
    TwoViewConfig,
    fit_two_view,
    overlapping_images,
    pairwise_matches,
    reference_match,
    sweep_features,
    wrap_angle_rad,
)
from tests.conftest import PaperSet

REFERENCE_FILE = Path(__file__).parent / "data" / "paper_reference.json"
#: The fast path must give the reference's similarity within this on every pair.
AGREEMENT = 0.005


@pytest.fixture(scope="module")
def reference() -> dict[tuple[str, str], dict[str, float]]:
    doc = json.loads(REFERENCE_FILE.read_text())
    return {tuple(key.split("|")): value for key, value in doc.items()}  # type: ignore[misc]


@pytest.fixture(scope="module")
def pairs(paper_sets: dict[str, PaperSet]) -> list[tuple[PaperSet, PaperSet]]:
    return [
        (paper_sets[a], paper_sets[b]) for a, b in itertools.combinations(sorted(paper_sets), 2)
    ]


@pytest.fixture(scope="module")
def fast(paper_sets: dict[str, PaperSet]):  # type: ignore[no-untyped-def]
    names = sorted(paper_sets)
    got = pairwise_matches([paper_sets[n].images for n in names], every_offset=True)
    return {(names[i], names[j]): m for (i, j), m in got.items()}


def test_reference_file_covers_every_pair(reference, pairs) -> None:  # type: ignore[no-untyped-def]
    assert {(a.name, b.name) for a, b in pairs} == set(reference)


@pytest.mark.parametrize(("a", "b"), [("1", "2"), ("3_active", "4")])
def test_reference_file_matches_the_reference_code(paper_sets, reference, a, b) -> None:  # type: ignore[no-untyped-def]
    live = reference_match(paper_sets[a].images, paper_sets[b].images)
    stored = reference[(a, b)]
    assert live.image_shift == stored["image_shift"]
    assert live.similarity == pytest.approx(stored["similarity"], abs=1e-9)
    assert live.pixel_shift == pytest.approx(stored["pixel_shift"], abs=1e-9)


def test_fast_path_agrees_with_the_reference_on_every_pair(fast, reference, paper_sets) -> None:  # type: ignore[no-untyped-def]
    same_pairs = 0
    for (a, b), ref in reference.items():
        got = fast[(a, b)]
        assert (got.similarity >= DEFAULT_THRESHOLD) == (ref["similarity"] >= DEFAULT_THRESHOLD)
        assert got.similarity == pytest.approx(ref["similarity"], abs=AGREEMENT), (a, b)
        # Between different junctions the best offset is an argmax over noise (all
        # offsets score alike, about 0.25-0.3): offset and rotation mean nothing there.
        if paper_sets[a].same_junction(paper_sets[b]):
            same_pairs += 1
            assert got.image_shift == ref["image_shift"], (a, b)
            assert abs(wrap_angle_rad(got.rotation_rad - ref["rotation_rad"])) <= 0.01, (a, b)
    assert same_pairs == 36


def test_localizer_cascade_decides_as_the_reference(paper_sets, reference) -> None:  # type: ignore[no-untyped-def]
    # The decision path screens, then refines the best junction at every offset.
    for (a, b), ref in reference.items():
        matcher = FastMatcher()
        matcher.add(matcher.prepare(paper_sets[b].images))
        got = matcher.match(matcher.prepare(paper_sets[a].images))[0]
        assert (got.similarity >= DEFAULT_THRESHOLD) == (ref["similarity"] >= DEFAULT_THRESHOLD)
        assert got.similarity == pytest.approx(ref["similarity"], abs=AGREEMENT), (a, b)
        if paper_sets[a].same_junction(paper_sets[b]):
            assert got.image_shift == ref["image_shift"], (a, b)


def test_the_threshold_separates_same_from_different_junctions(fast, paper_sets, reference) -> None:  # type: ignore[no-untyped-def]
    same = {
        k: m.similarity for k, m in fast.items() if paper_sets[k[0]].same_junction(paper_sets[k[1]])
    }
    different = [m.similarity for k, m in fast.items() if k not in same]
    assert len(same) == 36 and len(different) == 19
    # The paper's algorithm (quarter scale) recognises every same-junction pair and
    # rejects every different one, with room on both sides. The hardest same pair is
    # 1_active vs 2_noise, views 90 degrees apart: 0.373 (0.357 at full resolution,
    # which is not the paper's algorithm).
    assert max(different) < DEFAULT_THRESHOLD - 0.02
    assert min(same.values()) >= DEFAULT_THRESHOLD + 0.01
    assert reference[("1_active", "2_noise")]["similarity"] == pytest.approx(0.373, abs=0.0005)
    for k in same:
        assert reference[k]["similarity"] >= DEFAULT_THRESHOLD, k


def _rotation_errors(fast, paper_sets, attribute: str) -> list[float]:  # type: ignore[no-untyped-def]
    errors = []
    for (a, b), m in fast.items():
        sa, sb = paper_sets[a], paper_sets[b]
        if sa.same_junction(sb):
            errors.append(abs(wrap_angle_rad(getattr(m, attribute) - (sb.yaw_rad - sa.yaw_rad))))
    assert len(errors) == 36
    return errors


def test_pinhole_rotation_matches_the_recorded_yaw_difference(fast, paper_sets) -> None:  # type: ignore[no-untyped-def]
    errors = _rotation_errors(fast, paper_sets, "rotation_pinhole_rad")
    assert np.mean(errors) <= 0.03
    assert max(errors) <= 0.07


def test_paper_rotation_is_as_good_as_the_paper_says(fast, paper_sets) -> None:  # type: ignore[no-untyped-def]
    # The paper's linear pixel-to-angle mean: about 0.05 rad on average, but one
    # outlying peak among the six pairs can pull it off by a quarter radian.
    errors = _rotation_errors(fast, paper_sets, "rotation_rad")
    assert np.mean(errors) <= 0.06
    assert max(errors) <= 0.3


@pytest.fixture(scope="module")
def keypoints(paper_sets):  # type: ignore[no-untyped-def]
    return {name: sweep_features(s.images) for name, s in paper_sets.items()}


def _two_view_errors(paper_sets, keypoints, config: TwoViewConfig) -> list[float]:  # type: ignore[no-untyped-def]
    errors = []
    for a, b in itertools.combinations(sorted(paper_sets), 2):
        sa, sb = paper_sets[a], paper_sets[b]
        if sa.same_junction(sb):
            fit = fit_two_view(keypoints[a], keypoints[b], config)
            assert fit is not None, (a, b)
            errors.append(abs(wrap_angle_rad(fit.rotation_rad - (sb.yaw_rad - sa.yaw_rad))))
    assert len(errors) == 36
    return errors


def test_two_view_rotation_with_the_tilt_free_beats_the_paper(paper_sets, keypoints) -> None:  # type: ignore[no-untyped-def]
    # The robot stands up to 0.05 rad off level in these sets (info.txt's roll and
    # pitch, which the localizer does not see). The planar model alone is thrown off
    # across entries; with the relative tilt free, the error is a fifth of the paper's
    # estimate's (0.05 rad on average, asserted above).
    planar = _two_view_errors(paper_sets, keypoints, TwoViewConfig(tilt=False))
    assert np.mean(planar) > 0.05
    assert max(planar) > 0.15
    tilted = _two_view_errors(paper_sets, keypoints, TwoViewConfig())
    assert np.mean(tilted) <= 0.01
    assert max(tilted) <= 0.07
    assert sorted(tilted)[-2] <= 0.035  # one pair (1_active, 2) at 0.061


def test_two_view_check_on_overlapping_images_keeps_every_decision(
    fast, paper_sets, keypoints
) -> None:  # type: ignore[no-untyped-def]
    # As the localizer runs it: the NCC's rotation as the guess, so each image is
    # matched only with the images of the other sweep it can overlap. Same-junction
    # pairs still pass the localizer's 48 inliers; different ones stay far below.
    config = TwoViewConfig()
    gated = 0
    for a, b in itertools.combinations(sorted(paper_sets), 2):
        guess = fast[(a, b)].rotation_rad
        overlap = overlapping_images(keypoints[a], keypoints[b], guess, config.overlap_margin_rad)
        assert overlap is not None
        gated += sum(len(row) < paper_sets[a].images.count for row in overlap)
        fit = fit_two_view(keypoints[a], keypoints[b], config, guess)
        if paper_sets[a].same_junction(paper_sets[b]):
            assert fit is not None and fit.inliers >= 48, (a, b, fit)
        else:
            assert fit is None or fit.inliers < 24, (a, b, fit)
    assert gated == 55 * paper_sets["1"].images.count  # every image of every pair


def _true_nodes(visits: list[PaperSet]) -> list[int]:
    """Junction of each visit, numbered in first-visit order, from recorded positions."""
    firsts: list[PaperSet] = []
    out = []
    for v in visits:
        for i, f in enumerate(firsts):
            if v.same_junction(f):
                out.append(i)
                break
        else:
            firsts.append(v)
            out.append(len(firsts) - 1)
    return out


@pytest.mark.parametrize(
    "sequence",
    [
        ["1", "4", "2", "10", "3"],
        ["1_noise", "4", "2_active", "10", "3_noise", "4", "2_noise", "10", "3_active"],
    ],
)
def test_map_of_a_visit_sequence_is_the_true_map(paper_sets, sequence) -> None:  # type: ignore[no-untyped-def]
    visits = [paper_sets[name] for name in sequence]
    localizer = Localizer()
    decisions = [localizer.localize(v.images) for v in visits]
    truth = _true_nodes(visits)
    assert [d.node for d in decisions] == truth
    assert [d.known for d in decisions] == [truth.index(t) != i for i, t in enumerate(truth)]
    true_edges = []
    for u, v in zip(truth, truth[1:], strict=False):
        if u != v and {u, v} not in [set(e) for e in true_edges]:
            true_edges.append((u, v))
    got = [(e.u, e.v) for e in localizer.map.edges()]
    assert got == true_edges
    assert [e.label for e in localizer.map.edges()] == list(range(1, len(true_edges) + 1))
