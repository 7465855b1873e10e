"""Dead reckoning's allowance for the heading's drift (:mod:`localizer.odometry`):
the path's moment, a long loop of 20 m pipes closed with a heading bias, twins kept
apart where the moment is small, the allowance widened by ``--odometry-drift`` and
used as the competing maps' odometry weight."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer import LocalizerConfig
from pipemap.localizer.odometry import DeadReckoning, PathMoment, drift_allowed

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
