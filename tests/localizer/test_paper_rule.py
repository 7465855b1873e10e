"""The paper's decision rule (:meth:`LocalizerConfig.paper_rule`, :data:`PAPER`): the
similarity threshold alone decides, with none of the checks pipemap adds."""

from __future__ import annotations

from dataclasses import fields, replace

import cv2
import numpy as np
import pytest

from pipemap.localizer import FastConfig, ImageSet, Localizer, LocalizerConfig
from pipemap.localizer.config import (
    COST_SWITCHES,
    PAPER,
    PIPEMAP_CHECKS,
    PIPEMAP_REFINEMENTS,
)
from tests.localizer.junctions import CORNER_EXITS, FOV_RAD, TEE_EXITS, junction, views


def test_the_paper_rule_has_none_of_pipemaps_checks() -> None:
    # Every switch of the settings that can change a decision: the paper's rule keeps
    # active vision (its Algorithm 3) and nothing else. A check added later that the
    # rule kept fails here; a switch of cost alone must say it changes no decision.
    switches = {
        f.name: getattr(PAPER, f.name)
        for f in fields(PAPER)
        if f.type == "bool" and f.name not in COST_SWITCHES
    }
    assert {name for name, on in switches.items() if on} == {"active_vision"}
    assert all(getattr(PAPER, name) == getattr(LocalizerConfig(), name) for name in COST_SWITCHES)
    assert set(PIPEMAP_CHECKS) | set(PIPEMAP_REFINEMENTS) == set(switches) - {"active_vision"}
    assert LocalizerConfig().paper_rule() == PAPER
    assert (PAPER.threshold, PAPER.fast, PAPER.lamp) == (0.36, FastConfig(), None)
    # The rule changes the checks, never the threshold, similarity or lighting.
    mine = LocalizerConfig(threshold=0.5, lamp=True, fast=FastConfig(fine_downsample=2))
    assert mine.paper_rule() == replace(PAPER, threshold=0.5, lamp=True, fast=mine.fast)


def _look_alike(seed: int, other: int) -> ImageSet:
    """Junction ``seed``'s sweep, blurred, under fine texture of its own: the NCC at
    the paper's quarter scale finds the junction (about 0.43), its keypoints do not."""
    coarse = np.stack([cv2.GaussianBlur(v.astype(np.float32), (0, 0), 8.0) for v in views(seed)])
    rng = np.random.default_rng(other)
    fine = np.stack(
        [cv2.GaussianBlur(rng.normal(size=v.shape).astype(np.float32), (0, 0), 1.0) for v in coarse]
    )
    return ImageSet(coarse + 20.0 * fine / float(fine.std()), fov_rad=FOV_RAD)


#: A tour every check of pipemap's would decide otherwise: (sweep, exits, dead
#: reckoning, odometer). Visit 2 returns to junction 0 with two exits where it has three
#: ports, 12 m from where the robot was there; visit 3 is the same sweep at once (no
#: pipe driven); visit 4 is junction 0's look-alike.
TOUR = (
    (junction(0), TEE_EXITS, (0.0, 0.0), 0.0),
    (junction(1), CORNER_EXITS, (3.0, 0.0), 3.0),
    (junction(0, roll=1), (0.4, 2.0), (9.0, 9.0), 6.0),
    (junction(0, roll=1), (0.4, 2.0), (9.0, 9.0), 6.0),
    (_look_alike(0, 7), TEE_EXITS, (0.0, 0.0), 9.0),
)


def _tour(config: LocalizerConfig) -> list[tuple[int, bool, bool]]:
    """Each visit's junction, known or new, and whether the two-view fit was used."""
    loc = Localizer(config)
    decisions = [loc.localize(s, exits_rad=e, position_m=p, odometer_m=o) for s, e, p, o in TOUR]
    return [(d.node, d.known, d.two_view is not None) for d in decisions]


def test_the_paper_rule_decides_by_the_threshold_alone() -> None:
    loc = Localizer(PAPER)
    decisions = [loc.localize(s, exits_rad=e, position_m=p, odometer_m=o) for s, e, p, o in TOUR]
    # Known exactly when the best similarity reaches 0.36, whatever the exits, the
    # dead reckoning, the visit before or the keypoints say.
    assert [(d.node, d.known) for d in decisions] == [
        (0, False),
        (1, False),
        (0, True),
        (0, True),
        (0, True),
    ]
    assert all((d.similarity >= PAPER.threshold) == d.known for d in decisions[1:])
    assert 0.36 < decisions[4].similarity < 0.6
    assert all(d.two_view is None and d.rejected == () for d in decisions)


# Each check on top of the paper's rule (with what it needs: the keypoint check
# needs the two-view fit) changes a decision of the tour.
_NEEDS = {"verify": {"two_view": True}}


@pytest.mark.parametrize("check", PIPEMAP_CHECKS)
def test_each_of_pipemaps_checks_changes_the_tour(check: str) -> None:
    base = replace(PAPER, **_NEEDS.get(check, {}))
    assert _tour(replace(base, **{check: True})) != _tour(base)
