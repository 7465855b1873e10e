"""End to end: the simulator's `perfect` and `noise` tours of `paper`, localized.

Issue 3's point: every known/unknown decision right, and the rotation reported for
every recognised junction within 0.01 rad of the true heading difference. In `noise`
the robot stands about 3 cm off centre, where walls 10 cm away shift by tens of
pixels (parallax), and the paper's peak-shift rotation misses by up to 0.13 rad; the
two-view fit models it. The camera is lamp-lit (the default since issue 20): the sets
are normalised as the localizer does for a lamp-lit camera.
"""

from __future__ import annotations

import itertools

import cv2
import numpy as np
import pytest

from pipemap.localizer import (
    ImageSet,
    Localizer,
    LocalizerConfig,
    fit_two_view,
    normalised,
    pairwise_matches,
    sweep_features,
    wrap_angle_rad,
)
from pipemap.sim import CameraSpec, Condition, Episode, SimConfig, World, build_network

TOLERANCE_RAD = 0.01


@pytest.fixture(scope="module")
def paper_world():  # type: ignore[no-untyped-def]
    with World(build_network("paper"), seed=0) as world:
        yield world


Tour = list[tuple[str, float, ImageSet]]
_TOURS: dict[tuple[Condition, int, float], Tour] = {}


def _tour(world: World, condition: Condition, seed: int, lamp: float = 1.0) -> Tour:
    """(true node, true heading, grayscale set) of every visit, at 400 px (rendered
    once per module)."""
    if (condition, seed, lamp) in _TOURS:
        return _TOURS[condition, seed, lamp]
    camera = CameraSpec(resolution_px=400, lamp_strength=lamp)
    config = SimConfig(condition, seed=seed, camera=camera)
    visits = []
    for v in Episode(world, config).visits():
        gray = np.stack([cv2.cvtColor(im, cv2.COLOR_RGB2GRAY) for im in v.sweep.images])
        images = ImageSet(gray, camera_angle_rad=v.sweep.camera_angle_rad)
        visits.append((v.node, v.pose.yaw_rad, images))
    _TOURS[condition, seed, lamp] = visits
    return visits


#: (condition, seed, lamp strength) of the tours.
TOURS = [
    (Condition.NOISE, 0, 1.0),
    (Condition.NOISE, 1, 0.0),
    (Condition.NOISE, 1, 1.0),
    (Condition.PERFECT, 0, 1.0),
]

#: The tours as the bare localizer decides them. Known failure under the lamp (issue 20,
#: see docs/lighting.md): in noise seed 1 the return to the capped entry S scores 0.21
#: by NCC, below different junctions, so it is not among the candidates the two-view
#: check fits; the same tour evenly lit is right. (Its pairs all fit, since the lamp's
#: normalisation blurs at a whole factor, stop 35: before, the fit of two visits of C
#: turned them by half a turn.)
LOCALIZER_TOURS = [
    pytest.param(*tour, marks=pytest.mark.xfail(strict=True))
    if tour == (Condition.NOISE, 1, 1.0)
    else tour
    for tour in TOURS
]


@pytest.mark.parametrize(("condition", "seed", "lamp"), TOURS)
def test_every_pair_of_visits_of_a_junction(
    paper_world: World, condition: Condition, seed: int, lamp: float
) -> None:
    """The two-view rotation between any two visits of one junction (10 pairs per
    tour: S twice, A three times, C four times), against the true headings."""
    tour = _tour(paper_world, condition, seed, lamp)
    sets = [normalised(images) if lamp else images for _, _, images in tour]
    features = [sweep_features(images) for images in sets]
    ncc = pairwise_matches(sets)
    errors, paper_errors = [], []
    for i, j in itertools.combinations(range(len(tour)), 2):
        (node_i, heading_i, _), (node_j, heading_j, _) = tour[i], tour[j]
        if node_i != node_j:
            continue
        paper = ncc[i, j].rotation_rad
        fit = fit_two_view(features[i], features[j], guess_rad=paper)
        if fit is None:  # under a lamp the NCC may turn a cross: as the localizer does
            fit = fit_two_view(features[i], features[j])
        assert fit is not None, f"no fit between visits {i} and {j} of {node_i}"
        true = wrap_angle_rad(heading_j - heading_i)
        errors.append(abs(wrap_angle_rad(fit.rotation_rad - true)))
        paper_errors.append(abs(wrap_angle_rad(paper - true)))
    assert len(errors) == 10
    assert max(errors) < TOLERANCE_RAD, (errors, paper_errors)


@pytest.mark.parametrize(("condition", "seed", "lamp"), LOCALIZER_TOURS)
def test_the_localizer_reports_the_two_view_rotation(
    paper_world: World, condition: Condition, seed: int, lamp: float
) -> None:
    """At the defaults every known/unknown decision is right (issue 3), and every
    revisit reports a two-view rotation within 0.01 rad."""
    localizer = Localizer(LocalizerConfig(lamp=lamp > 0.0))
    first: dict[int, tuple[str, float]] = {}  # map node -> (true node, heading)
    seen: set[str] = set()
    for node, heading, images in _tour(paper_world, condition, seed, lamp):
        decision = localizer.localize(images)
        assert decision.known == (node in seen), f"wrong known/new decision at {node}"
        seen.add(node)
        if not decision.known:
            first[decision.node] = (node, heading)
            continue
        true_node, true_heading = first[decision.node]
        assert true_node == node, f"{node} taken for {true_node}"
        assert decision.two_view is not None, f"no two-view fit at {node}"
        true = wrap_angle_rad(true_heading - heading)
        assert decision.rotation_rad == decision.two_view.rotation_rad
        assert abs(wrap_angle_rad(decision.two_view.rotation_rad - true)) < TOLERANCE_RAD
    assert len(first) == 7
