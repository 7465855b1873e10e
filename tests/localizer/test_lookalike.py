"""Junctions that look the same: identical sweeps that only dead reckoning tells apart
(``LocalizerConfig.odometry_check``)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer import Localizer, LocalizerConfig
from tests.conftest import PaperSet

#: Two look-alike junctions 2 m apart, and a third, different one between them.
ALIKE_A, OTHER, ALIKE_B = (0.0, 0.0), (1.0, 0.0), (2.0, 0.0)


def _tour(config: LocalizerConfig, paper_sets: dict[str, PaperSet]) -> list[tuple[int, bool]]:
    """A, X, B (B's sweep the very images of A's), X again, then B again: each visit's
    node and whether it was known."""
    same, other = paper_sets["1"].images, paper_sets["4"].images
    loc = Localizer(config)
    visits = [
        (same, ALIKE_A, 0.0),
        (other, OTHER, 1.0),
        (same, ALIKE_B, 2.0),
        (other, (1.04, 0.02), 3.0),
        (same, (2.05, -0.03), 4.0),
    ]
    out = []
    for images, position, odometer in visits:
        d = loc.localize(images, odometer_m=odometer, position_m=position)
        out.append((d.node, d.known))
    return out


def test_identical_sweeps_apart_by_odometry_are_two_junctions(
    paper_sets: dict[str, PaperSet],
) -> None:
    visits = _tour(LocalizerConfig(), paper_sets)
    assert visits == [(0, False), (1, False), (2, False), (1, True), (2, True)]


def test_without_the_odometry_check_the_look_alike_is_merged(
    paper_sets: dict[str, PaperSet],
) -> None:
    # The same sweeps, the check off: appearance alone takes B for A (a false merge).
    visits = _tour(LocalizerConfig(odometry_check=False), paper_sets)
    assert visits[2] == (0, True) and visits[4] == (0, True)


def test_a_revisit_within_the_drift_tolerance_is_recognised(
    paper_sets: dict[str, PaperSet],
) -> None:
    # 0.3 m plus 0.5 % of the distance driven: after 40 m a revisit 0.45 m off is still
    # the junction; the tolerance stops growing at 0.6 m.
    images = paper_sets["1"].images
    loc = Localizer()
    loc.localize(images, odometer_m=0.0, position_m=(0.0, 0.0))
    loc.localize(paper_sets["4"].images, odometer_m=20.0, position_m=(5.0, 0.0))
    assert loc.localize(images, odometer_m=40.0, position_m=(0.45, 0.0)).known
    # Seen 100 m of driving before (0.4 % of it is 0.4 m, under the limit), 0.65 m
    # off is another junction.
    loc2 = Localizer()
    loc2.localize(images, odometer_m=300.0, position_m=(0.0, 0.0))
    loc2.localize(paper_sets["4"].images, odometer_m=320.0, position_m=(5.0, 0.0))
    assert not loc2.localize(images, odometer_m=400.0, position_m=(0.65, 0.0)).known


def _loop(config: LocalizerConfig, paper_sets: dict[str, PaperSet], off_m: float) -> bool:
    """Whether a junction first seen at odometer 0 is recognised after 252 m of
    driving, ``off_m`` from where the dead reckoning put it then. The one visit
    between is 2 m away: the path's moment is small, so the heading's allowance
    (``odometry_heading_drift_per_m``) stays under 0.6 m and the loop's rules."""
    images = paper_sets["1"].images
    loc = Localizer(config)
    loc.localize(images, odometer_m=0.0, position_m=(0.0, 0.0))
    loc.localize(paper_sets["4"].images, odometer_m=126.0, position_m=(2.0, 0.0))
    return loc.localize(images, odometer_m=252.0, position_m=(0.0, off_m)).known


def test_a_long_loop_may_drift_past_the_limit(paper_sets: dict[str, PaperSet]) -> None:
    # random:200 seed 4711 at 96 px: a loop closed 0.61 m off after 252 m of driving,
    # past the 0.6 m limit; 0.4 % of 252 m is 1.0 m.
    assert _loop(LocalizerConfig(), paper_sets, 0.61)
    assert not _loop(LocalizerConfig(odometry_loop_drift_per_m=0.0), paper_sets, 0.61)
    # Twins 2 m apart are still two junctions after that drive.
    assert not _loop(LocalizerConfig(), paper_sets, 2.0)


#: A loop round a 40 m square of 20 m pipes, a junction at each corner and mid-side,
#: as the dead reckoning had it with a heading drift of 3.8e-4 rad a metre (as on
#: ``random:200`` seed 4711 with pipes of 1-20 m; ``tests/localizer/test_odometry.py``
#: integrates it): back at the start after 160 m, 1.71 m from where it began.
SQUARE_DEAD_RECKONED = [
    (0.0, 0.0),
    (20.000, 0.076),
    (39.998, 0.304),
    (39.618, 20.300),
    (39.087, 40.293),
    (19.098, 39.609),
    (-0.884, 38.774),
    (0.103, 18.798),
    (1.243, -1.169),
]


def _square(
    config: LocalizerConfig, paper_sets: dict[str, PaperSet], end: tuple[float, float]
) -> bool:
    """Whether the start is recognised at the end of :data:`SQUARE_DEAD_RECKONED`
    with the last position replaced by ``end`` (the visits between are other
    junctions, 20 m apart)."""
    others = [paper_sets[name].images for name in ("2", "3", "4", "10")]
    loc = Localizer(config)
    positions = [*SQUARE_DEAD_RECKONED[:-1], end]
    for k, position in enumerate(positions):
        images = paper_sets["1"].images if k in (0, len(positions) - 1) else others[k % 4]
        decision = loc.localize(images, odometer_m=20.0 * k, position_m=position)
    return decision.known


def test_a_loop_of_long_pipes_closes_despite_the_heading_s_drift(
    paper_sets: dict[str, PaperSet],
) -> None:
    # 1.71 m from the start, past max(0.6 m, 0.4 % of 160 m): the old tolerances
    # make the revisit a false new junction.
    end = SQUARE_DEAD_RECKONED[-1]
    assert _square(LocalizerConfig(), paper_sets, end)
    assert not _square(LocalizerConfig(odometry_heading_drift_per_m=0.0), paper_sets, end)
    # The allowance follows the path: 4 m off is farther than its 3 m.
    assert not _square(LocalizerConfig(), paper_sets, (4.0, 0.0))


def test_without_positions_nothing_changes(paper_sets: dict[str, PaperSet]) -> None:
    images = paper_sets["1"].images
    loc = Localizer()
    loc.localize(images)
    loc.localize(paper_sets["4"].images)
    assert loc.localize(images).known


@pytest.mark.parametrize(
    "field",
    [
        "odometry_radius_m",
        "odometry_drift_per_m",
        "odometry_limit_m",
        "odometry_loop_drift_per_m",
        "odometry_heading_drift_per_m",
    ],
)
def test_a_negative_tolerance_is_refused(field: str) -> None:
    with pytest.raises(LocalizerError, match="odometry"):
        replace(LocalizerConfig(), **{field: -0.1})


def test_where_nothing_tells_two_junctions_apart_the_decision_says_so(
    paper_sets: dict[str, PaperSet],
) -> None:
    # A and B have the very same sweep and no ports; the odometry kept them apart when
    # B was first seen. A visit with no dead reckoning fits both equally: the decision
    # names the other as alike instead of passing its choice for certain.
    same, other = paper_sets["1"].images, paper_sets["4"].images
    loc = Localizer()
    assert not loc.localize(same, position_m=ALIKE_A).known
    assert not loc.localize(other, position_m=OTHER).known
    assert not loc.localize(same, position_m=ALIKE_B).known
    assert loc.localize(other, position_m=OTHER).node == 1
    blind = loc.localize(same)
    assert blind.known and blind.node in (0, 2)
    assert blind.alike == (({0, 2} - {blind.node}).pop(),)
    assert "as alike: " in blind.describe()
    # With its dead reckoning the same visit is told apart: no alike.
    loc.localize(other, position_m=OTHER)
    placed = loc.localize(same, position_m=(2.05, -0.03), odometer_m=4.0)
    assert placed.known and placed.node == 2 and placed.alike == ()


def test_different_junctions_are_not_named_alike(paper_sets: dict[str, PaperSet]) -> None:
    names = ["1", "4", "10"]
    sets = [paper_sets[n] for n in names]
    assert not any(a.same_junction(b) for a in sets for b in sets if a is not b)
    loc = Localizer()
    for one in sets:
        assert not loc.localize(one.images).known
    again = loc.localize(paper_sets["1_noise"].images)
    assert again.known and again.node == 0 and again.alike == ()
