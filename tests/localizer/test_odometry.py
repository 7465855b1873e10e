"""Dead reckoning's allowance for the heading's drift (:mod:`localizer.odometry`):
the path's moment, a long loop of 20 m pipes closed with a heading bias, twins kept
apart where the moment is small, the allowance widened by ``--odometry-drift`` and
used as the competing maps' odometry weight; the heading's drift fitted to the loops
the robot closes (:class:`HeadingBias`), which narrows the allowance over laps of
long pipes while the revisits stay recognised and twins stay apart."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer import Localizer, LocalizerConfig
from pipemap.localizer.odometry import DeadReckoning, HeadingBias, PathMoment, drift_allowed
from tests.conftest import PaperSet

#: The heading drift of ``random:200`` seed 4711's dead reckoning on pipes of 1-20 m:
#: its error was 3.7e-4 to 3.8e-4 of the path's moment at every revisit.
MEASURED_RAD_PER_M = 3.8e-4

#: A loop round a 40 m square of 20 m pipes, a junction at each corner and mid-side.
SQUARE = [(0, 0), (20, 0), (40, 0), (40, 20), (40, 40), (20, 40), (0, 40), (0, 20), (0, 0)]


def _dead_reckoned(
    corners: list[tuple[float, float]], heading_rad_per_m: float, steps: int = 200
) -> list[tuple[tuple[float, float], float]]:
    """The dead reckoning and the odometer at each corner of a drive along straight
    pipes whose heading estimate drifts by ``heading_rad_per_m`` a metre driven."""
    x, y, s = float(corners[0][0]), float(corners[0][1]), 0.0
    out = [((x, y), s)]
    for (ax, ay), (bx, by) in zip(corners, corners[1:], strict=False):
        length = math.hypot(bx - ax, by - ay)
        heading = math.atan2(by - ay, bx - ax)
        step = length / steps
        for k in range(steps):
            error = heading_rad_per_m * (s + (k + 0.5) * step)
            x += step * math.cos(heading + error)
            y += step * math.sin(heading + error)
        s += length
        out.append(((x, y), s))
    return out


def _closes(config: LocalizerConfig, drive: list[tuple[tuple[float, float], float]]) -> bool:
    """Whether the last visit may be the first's junction by dead reckoning."""
    dr = DeadReckoning(config)
    for k, (position, odometer) in enumerate(drive):
        dr.at(position, odometer)
        if k == 0:
            dr.remember(0)
    return dr.near(0)


#: :data:`SQUARE` with a twin junction 0.9 m along the first pipe from the start.
SQUARE_WITH_TWIN = [SQUARE[0], (0.9, 0.0), *SQUARE[1:]]


def _laps(config: LocalizerConfig, laps: int, rad_per_m: float) -> DeadReckoning:
    """Dead reckoning after ``laps`` rounds of :data:`SQUARE_WITH_TWIN` with a heading
    drift of ``rad_per_m``, each lap's visits to the start (junction 0) and its twin
    (junction 1) recognised as the localizer would (the last lap's start excepted:
    the test asks about it)."""
    corners = SQUARE_WITH_TWIN[:-1] * laps + [SQUARE_WITH_TWIN[0]]
    drive = _dead_reckoned(corners, rad_per_m)
    dr = DeadReckoning(config)
    per_lap = len(SQUARE_WITH_TWIN) - 1
    for k, (position, odometer) in enumerate(drive):
        dr.at(position, odometer)
        if k in (0, 1):
            dr.remember(k)
        elif k % per_lap in (0, 1) and k < len(drive) - 1:
            dr.closed(k % per_lap)
    return dr


def test_laps_of_20_m_pipes_pin_the_heading_s_drift_down() -> None:
    # Five laps (805 m): the dead reckoning is metres off at the end, the fit takes
    # it out, and the allowance narrows to what the fit leaves uncertain.
    fitted = _laps(LocalizerConfig(), 5, MEASURED_RAD_PER_M)
    raw = _laps(LocalizerConfig(odometry_heading_bias=False), 5, MEASURED_RAD_PER_M)
    assert raw.offset_m(0) is not None and raw.offset_m(0) > 5.0
    assert fitted.offset_m(0) is not None and fitted.offset_m(0) < 0.1
    assert fitted.near(0) and raw.near(0)  # the wide allowance covers the raw drift too
    assert fitted.heading_drift_per_m() < 1.5e-4 < raw.heading_drift_per_m()
    assert fitted.tolerance_for(0) < 0.25 * raw.tolerance_for(0)
    # The fitted error: 3.8e-4 rad a metre, 0.31 rad at the end.
    assert fitted.bias.heading_rad(805.0) == pytest.approx(MEASURED_RAD_PER_M * 805.0, rel=0.05)
    assert raw.bias.closures == []


def test_a_tight_allowance_recognises_the_lap_once_the_drift_is_fitted() -> None:
    # After five laps the allowance is tight (the moment of the last lap only, at the
    # fit's uncertainty; no loop allowance): the start is recognised where its
    # corrected position is, while the raw dead reckoning lies well outside it.
    fitted = _laps(LocalizerConfig(), 5, MEASURED_RAD_PER_M)
    tight = fitted.tolerance_for(0)
    assert tight < 1.0 and fitted.near(0)
    assert fitted.offset_m(0) is not None and fitted.offset_m(0) < tight
    raw = _laps(LocalizerConfig(odometry_heading_bias=False), 5, MEASURED_RAD_PER_M)
    assert raw.offset_m(0) is not None and raw.offset_m(0) > 5.0 * tight
    # Before any loop is closed (one lap, its end the question) the wide allowances
    # hold.
    one = _laps(LocalizerConfig(), 1, MEASURED_RAD_PER_M)
    assert one.heading_drift_per_m() == pytest.approx(0.0006)


def test_twins_stay_apart_after_laps_of_long_pipes() -> None:
    # After five laps the twin 0.9 m from the start is another junction; without the
    # fit the allowance has grown to take it in.
    fitted = _laps(LocalizerConfig(), 5, MEASURED_RAD_PER_M)
    raw = _laps(LocalizerConfig(odometry_heading_bias=False), 5, MEASURED_RAD_PER_M)
    assert fitted.near(0) and not fitted.near(1)
    assert raw.near(1)
    assert fitted.log_likelihood(0) > fitted.log_likelihood(1)


def test_no_drift_fits_no_drift() -> None:
    # Laps with an exact heading: nothing to take out, the positions stay as given.
    dr = _laps(LocalizerConfig(), 3, 0.0)
    assert dr.bias.heading_rad(500.0) == pytest.approx(0.0, abs=1e-9)
    assert dr.offset_m(0) == pytest.approx(0.0, abs=1e-9)
    assert len(dr.bias.closures) == 4  # laps 2 and 3: the start (not the last) and its twin


def test_a_broken_line_runs_on_straight_past_the_last_closure() -> None:
    bias = HeadingBias(0.3)
    for s in range(0, 401, 20):
        bias.add(float(s), 0.0, float(s))
    bias.knots = np.array([0.01, 0.02])  # knots at 100 m and 200 m
    assert bias.heading_rad(50.0) == pytest.approx(0.005)
    assert bias.heading_rad(400.0) == pytest.approx(0.04)


def test_the_localizer_closes_a_loop_at_each_recognised_revisit(
    paper_sets: dict[str, PaperSet],
) -> None:
    # The same sweep twice, 2 m apart by dead reckoning: known, and the loop is fitted.
    loc = Localizer(LocalizerConfig(odometry_loop_drift_per_m=0.05))
    first = loc.localize(paper_sets["1"].images, odometer_m=0.0, position_m=(0.0, 0.0))
    other = loc.localize(paper_sets["4"].images, odometer_m=20.0, position_m=(20.0, 0.0))
    again = loc.localize(paper_sets["1"].images, odometer_m=40.0, position_m=(0.0, 0.0))
    assert not first.known and not other.known and again.known
    assert loc._odometry.bias.closures == [(0, 2)]


def test_the_moment_of_a_run_out_and_back() -> None:
    # 40 m out along x and back: the heading error at each metre swings the rest of
    # the run, |∫ s dp| = 40²/2 - (80² - 40²)/2 = 1600 m².
    path = PathMoment()
    path.add((0.0, 0.0), 0.0)
    start = path.mark
    path.add((40.0, 0.0), 40.0)
    turn = path.mark
    path.add((0.0, 0.0), 80.0)
    assert start is not None and turn is not None
    assert path.since(start) == pytest.approx(1600.0)
    assert path.since(turn) == pytest.approx(800.0)  # 40 m back only: 40²/2
    # A visit without a position adds nothing: the next leg runs from the last one.
    path.add(None, 90.0)
    assert path.since(start) == pytest.approx(1600.0)


def test_a_long_loop_of_20_m_pipes_with_a_heading_bias_closes() -> None:
    drive = _dead_reckoned(SQUARE, MEASURED_RAD_PER_M)
    (x, y), odometer = drive[-1]
    off = math.hypot(x, y)
    # 160 m of driving: the old tolerances allow max(0.6 m, 0.4 % of 160 m) = 0.64 m.
    assert off > 1.5 and odometer == pytest.approx(160.0)
    assert _closes(LocalizerConfig(), drive)
    assert not _closes(LocalizerConfig(odometry_heading_drift_per_m=0.0), drive)
    # The allowance is the moment's: a heading drift well past the configured one
    # is not covered.
    assert not _closes(LocalizerConfig(), _dead_reckoned(SQUARE, 3.0 * MEASURED_RAD_PER_M))


def test_twins_stay_apart_where_the_moment_is_small() -> None:
    # Ten rounds of a 1 m square (40 m of driving; a short-pipe network's walk): the
    # moment stays small, and a twin 0.9 m from the first junction is another one.
    square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] * 10 + [(0.0, 0.0)]
    drive = _dead_reckoned(square, MEASURED_RAD_PER_M)
    assert _closes(LocalizerConfig(), drive)
    (x, y), odometer = drive[-1]
    twin = [*drive[:-1], ((x + 0.9, y), odometer)]
    assert not _closes(LocalizerConfig(), twin)
    dr = DeadReckoning(LocalizerConfig())
    for k, (position, s) in enumerate(twin):
        dr.at(position, s)
        if k == 0:
            dr.remember(0)
    assert dr.tolerance_for(0) == pytest.approx(dr.tolerance_m)  # the capped one rules


def test_the_heading_allowance_widens_with_the_robot_s_drift() -> None:
    # A robot 4 times as poor (--odometry-drift 4) drifts 4 times as much.
    drive = _dead_reckoned(SQUARE, 4.0 * MEASURED_RAD_PER_M)
    plain = LocalizerConfig()
    assert not _closes(plain, drive)
    assert _closes(drift_allowed(plain, 4.0), drive)
    assert drift_allowed(plain, 4.0).odometry_heading_drift_per_m == pytest.approx(
        4.0 * plain.odometry_heading_drift_per_m
    )
    assert drift_allowed(plain, 4.0).odometry_heading_residual_per_m == pytest.approx(
        4.0 * plain.odometry_heading_residual_per_m
    )


def test_the_odometry_weight_follows_the_same_allowance() -> None:
    # The competing maps weigh a known junction by a Gaussian whose sigma is half its
    # tolerance: after the long loop, the wide one.
    drive = _dead_reckoned(SQUARE, MEASURED_RAD_PER_M)
    weights = {}
    for heading in (0.0, 0.0006):
        dr = DeadReckoning(LocalizerConfig(odometry_heading_drift_per_m=heading))
        for k, (position, odometer) in enumerate(drive):
            dr.at(position, odometer)
            if k == 0:
                dr.remember(0)
        off = math.dist(drive[-1][0], drive[0][0])
        assert dr.log_likelihood(0) == pytest.approx(
            -0.5 * (off / (0.5 * dr.tolerance_for(0))) ** 2
        )
        weights[heading] = dr.log_likelihood(0)
    assert weights[0.0006] > -2.0 > weights[0.0]


def test_a_negative_heading_drift_is_refused() -> None:
    with pytest.raises(LocalizerError, match="odometry"):
        replace(LocalizerConfig(), odometry_heading_drift_per_m=-1e-4)


def test_the_fit_s_floor_sets_how_tight_the_allowance_gets() -> None:
    # A floor as wide as the allowance without the fit leaves the twin inside.
    loose = LocalizerConfig(odometry_heading_residual_per_m=5e-4)
    assert _laps(LocalizerConfig(), 5, MEASURED_RAD_PER_M).heading_drift_per_m() < 1.5e-4
    assert _laps(loose, 5, MEASURED_RAD_PER_M).near(1)
    with pytest.raises(LocalizerError, match="odometry"):
        replace(LocalizerConfig(), odometry_heading_residual_per_m=-1e-4)


def test_until_the_loops_pin_the_drift_down_nothing_changes() -> None:
    # Ten rounds of a 1 m square (a short-pipe network's walk), the start recognised
    # at each: loops too small to trust the fit, so positions, tolerances and weights
    # are those without it, to the bit.
    square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] * 10 + [(0.0, 0.0)]
    drive = _dead_reckoned(square, MEASURED_RAD_PER_M)
    checks = {on: DeadReckoning(LocalizerConfig(odometry_heading_bias=on)) for on in (False, True)}
    for k, (position, odometer) in enumerate(drive):
        for dr in checks.values():
            dr.at(position, odometer)
            if k == 0:
                dr.remember(0)
            elif k % 4 == 0 and k < len(drive) - 1:
                dr.closed(0)
    fitted, raw = checks[True], checks[False]
    assert len(fitted.bias.closures) == 9 and not fitted.fitted()
    assert fitted.offset_m(0) == raw.offset_m(0)
    assert fitted.tolerance_for(0) == raw.tolerance_for(0)
    assert fitted.log_likelihood(0) == raw.log_likelihood(0)
    # The laps of 20 m pipes do pin it down after one lap.
    assert _laps(LocalizerConfig(), 2, MEASURED_RAD_PER_M).fitted()


def test_a_closing_visit_keeps_the_check_it_was_decided_by() -> None:
    # Five laps, the last start not yet recognised: its check as the localizer makes
    # it. Closing the loop refits the drift and anchors the junction here (its
    # tolerance falls to the radius); the check as it was stays for the explorer.
    dr = _laps(LocalizerConfig(), 5, MEASURED_RAD_PER_M)
    before = (dr.offset_m(0), dr.tolerance_for(0))
    assert dr.closing_check(0) is None  # this visit has closed nothing yet
    dr.closed(0)
    assert dr.closing_check(0) == before
    assert dr.tolerance_for(0) < before[1]
    assert dr.closing_check(1) is None  # another junction's: not this visit's
    dr.at((0.0, 0.0), 900.0)  # the next visit
    assert dr.closing_check(0) is None
