"""The geometry of a junction scan: pure functions of the range samples.

A scan is the robot turning once round in place while its front ranger reads:
``(heading, range)`` samples, the heading the gyro's estimate. From them come the
exits (:func:`opening_headings`), the wall points (:func:`wall_points`) and the
junction's centre: where the widest circle fits among the walls
(:func:`widest_centre`) or, at a shallow corner, where its two pipes' axes cross
(:func:`axes_crossing`). Also the pipe's cross-section as the rangers see it
(:data:`HALF_WIDTH_M`, :data:`SIDE_NOMINAL_M`). Nothing here drives the robot.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

__all__ = [
    "HALF_WIDTH_M",
    "SIDE_NOMINAL_M",
    "axes_crossing",
    "opening_headings",
    "seen",
    "through_wall",
    "wall_points",
    "widest_centre",
]

#: Horizontal distance from the pipe axis to the wall at the rangers' height (5 cm).
HALF_WIDTH_M = math.sqrt(0.1**2 - 0.05**2)
#: Side range in a straight pipe with the robot centred (rays at 40 deg, 5 cm high).
SIDE_NOMINAL_M = HALF_WIDTH_M / math.sin(math.radians(40.0))

_CORNER_REACH_M = 0.16
_STRAIGHT_DEG = 10.0
#: The clearances within which circles count as the widest, tried in turn (see
#: :func:`axes_crossing`): the scan's tolerance first.
_ARM_TOLERANCES_M = (0.003, 0.006, 0.009)


def seen(samples: list[tuple[float, float]], forward_m: float, offsets: np.ndarray) -> np.ndarray:
    """Which ``offsets`` from the scan's centre lie inside the pipe: nearer than the
    wall the scan saw in their direction (the sample of nearest heading)."""
    yaws = np.array([y for y, _ in samples]) % (2.0 * math.pi)
    reach = forward_m + np.array([r for _, r in samples])
    order = np.argsort(yaws)
    yaws, reach = yaws[order], reach[order]
    bearing = np.arctan2(offsets[:, 1], offsets[:, 0]) % (2.0 * math.pi)
    after = np.searchsorted(yaws, bearing) % len(yaws)
    before = (after - 1) % len(yaws)
    gap_after = np.abs(np.remainder(yaws[after] - bearing + math.pi, 2.0 * math.pi) - math.pi)
    gap_before = np.abs(np.remainder(yaws[before] - bearing + math.pi, 2.0 * math.pi) - math.pi)
    nearest = np.where(gap_after < gap_before, after, before)
    inside: np.ndarray = np.linalg.norm(offsets, axis=1) < reach[nearest]
    return inside


def axes_crossing(
    samples: list[tuple[float, float]],
    forward_m: float,
    walls: np.ndarray,
    here: np.ndarray,
    guess: np.ndarray,
    openings: list[float],
    shallow_deg: float,
) -> np.ndarray | None:
    """Centre of a shallow corner: where the axes of its two pipes cross.

    Every point on a pipe's axis fits a circle of the pipe's radius, so the widest
    points of a corner's scan lie on two arms, one along each pipe. The apex fits a
    wider circle only by ``1/cos(turn/2)``: 8 mm for a 43 degree turn, about the
    tolerance of the scan, so the widest circle alone can settle anywhere on the
    arms (it missed a 137 degree corner by 8 cm). Instead each arm's axis is fitted to
    its points (their mean offset across the arm's direction) and the two axes are
    crossed. ``None`` when the corner is sharp (the widest circle is then clear), or
    when an arm has too few points to fit.
    """
    u = np.array([[math.cos(o), math.sin(o)] for o in openings])
    turn = math.pi - abs(math.remainder(openings[0] - openings[1], 2.0 * math.pi))
    if not math.radians(_STRAIGHT_DEG) < turn < math.radians(shallow_deg):
        return None  # sharp, or two ends of one straight pipe (an open entry)
    # The robot may stand well up one arm (the approach misjudged the distance), so
    # look twice as far as the widest-circle search does for both arms.
    offsets_m = np.arange(-_CORNER_REACH_M, _CORNER_REACH_M + 1e-9, 0.002)
    gx, gy = np.meshgrid(offsets_m, offsets_m)
    centres = here + np.stack([gx.ravel(), gy.ravel()], 1)
    centres = centres[seen(samples, forward_m, centres - here)]
    clearance, _ = cKDTree(walls).query(centres)
    normals = np.stack([-u[:, 1], u[:, 0]], axis=1)
    # The widest circles within the scan's tolerance; where those all lie on one arm
    # (the apex of a shallow corner is wider by ``1/cos(turn/2)``, and the robot may
    # stand far up the other arm), the tolerance grows until both arms hold some.
    for tolerance_m in _ARM_TOLERANCES_M:
        widest = centres[clearance >= clearance.max() - tolerance_m]
        offsets = _arm_offsets(widest, guess, u, normals)
        if offsets is not None:
            crossing: np.ndarray = np.linalg.solve(normals, offsets)
            return crossing
    return None


def _arm_offsets(
    widest: np.ndarray, guess: np.ndarray, u: np.ndarray, normals: np.ndarray
) -> np.ndarray | None:
    """Each arm's axis, as its points' mean offset along ``normals[k]`` (across the
    arm's direction ``u[k]``); ``None`` when an arm has fewer than 3 of the ``widest``
    points."""
    across = widest @ normals.T  # (P, 2): each point's offset across either arm
    # First guess of the arms: the direction each point lies in from the guess.
    arm = np.argmax((widest - guess) @ u.T, axis=1)
    offsets = np.zeros(2)
    for _ in range(3):
        for k in range(2):
            if np.count_nonzero(arm == k) < 3:
                return None
            offsets[k] = float(np.mean(across[arm == k, k]))
        # Then each point goes to the axis it lies nearer to, and the axes are refitted.
        arm = np.argmin(np.abs(across - offsets), axis=1)
    return offsets


def opening_headings(
    samples: list[tuple[float, float]], open_m: float, depth: float = 0.0
) -> list[float]:
    """Headings of the openings in a scan: runs of samples that see farther than
    ``open_m``.

    Each opening's heading is the mean of its samples that see at least ``depth``
    times as far as its farthest (all of them with 0). From a robot a few cm off
    the junction's centre an opening's near edges are lopsided, and so is the
    mean of all its samples (up to 0.26 rad off the pipe, measured); the deepest
    samples look along the pipe (at most 0.11 rad off with 0.8).
    """
    yaws = np.array([y for y, _ in samples])
    ranges = np.array([r for _, r in samples])
    is_open = ranges > open_m
    if is_open.all() or not is_open.any():
        return []
    # Group circularly: start from a closed sample so no opening is split in two.
    k = int(np.argmin(is_open))
    yaws = np.concatenate([yaws[k:], yaws[:k] + 2.0 * math.pi])
    ranges = np.concatenate([ranges[k:], ranges[:k]])
    is_open = np.concatenate([is_open[k:], is_open[:k]])
    openings: list[float] = []
    run: list[int] = []
    for i, open_ in enumerate(is_open):
        if open_:
            run.append(i)
        elif run:
            openings.append(_heading_of(yaws[run], ranges[run], depth))
            run = []
    if run:
        openings.append(_heading_of(yaws[run], ranges[run], depth))
    return [math.remainder(o, 2.0 * math.pi) for o in openings]


def through_wall(
    samples: list[tuple[float, float]], max_range_m: float, touch_m: float
) -> list[float]:
    """Headings where the front ranger passed through a wall: runs of samples that see
    nothing (``max_range_m``) with a sample nearer than ``touch_m`` among the two on
    either side (the ranger's noise can lift one of them).

    A robot put down off a junction's centre, where the walls are close (a dead end's
    cap, the far side of a T), swings its ranger on the nose through a wall as it turns:
    the reading falls to nothing, jumps to the sensor's limit and falls back. A real
    pipe's opening is not like that: the walls of its mouth recede, the readings grow
    on either side of it. Each run's heading is its middle."""
    n = len(samples)
    ranges = [r for _, r in samples]
    out: list[float] = []
    seen_start: set[int] = set()
    for i in range(n):
        if ranges[i] < max_range_m or ranges[i - 1] >= max_range_m or i in seen_start:
            continue
        seen_start.add(i)
        j = i
        while ranges[(j + 1) % n] >= max_range_m and (j + 1) % n != i:
            j += 1
        before = min(ranges[i - 1], ranges[i - 2])
        after = min(ranges[(j + 1) % n], ranges[(j + 2) % n])
        if before < touch_m and after < touch_m:
            yaws = np.unwrap([samples[k % n][0] for k in range(i, j + 1)])
            out.append(math.remainder(float(yaws[0] + yaws[-1]) / 2.0, 2.0 * math.pi))
    return out


def _heading_of(yaws: np.ndarray, ranges: np.ndarray, depth: float) -> float:
    deep = ranges >= depth * float(ranges.max())
    return float(np.mean(yaws[deep]))


def wall_points(
    samples: list[tuple[float, float]], here: np.ndarray, forward_m: float, open_m: float
) -> np.ndarray:
    """The wall points a scan from ``here`` saw (its samples nearer than ``open_m``;
    the ranger stands ``forward_m`` ahead of the robot's centre)."""
    return np.array(
        [
            here + (forward_m + r) * np.array([math.cos(y), math.sin(y)])
            for y, r in samples
            if r < open_m
        ]
    )


def widest_centre(points: np.ndarray, here: np.ndarray, expected: np.ndarray) -> np.ndarray:
    """Where the largest circle fits among the wall ``points`` (a 2 mm grid within
    8 cm of ``here``); among the ties (along a pipe's axis every point fits as wide a
    circle) the one nearest to ``expected``."""
    offsets = np.arange(-0.08, 0.0801, 0.002)
    gx, gy = np.meshgrid(offsets, offsets)
    centres = here + np.stack([gx.ravel(), gy.ravel()], 1)
    clearance = np.min(np.linalg.norm(centres[:, None, :] - points[None, :, :], axis=2), axis=1)
    widest = clearance >= clearance.max() - 0.003
    nearest = np.argmin(np.linalg.norm(centres[widest] - expected, axis=1))
    target: np.ndarray = centres[widest][int(nearest)]
    return target
