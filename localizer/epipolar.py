"""The planar epipolar constraint between two sweeps' bearings, and its fits.

Residuals ``a . (t x R b)`` of matched bearings, the exact grid count over rotations
and directions of motion (:func:`_grid_counts`), Gauss-Newton on the inliers, and
the refinement with the relative tilt free; the levelling by an IMU reading. Why
and how: :mod:`localizer.twoview`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from pipemap.localizer.similarity import wrap_angle_rad

if TYPE_CHECKING:
    from pipemap.localizer.twoview import TwoViewConfig, TwoViewFit


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Row-wise ``u x v`` of two ``(M, 3)`` arrays: ``np.cross``'s arithmetic without
    its axis handling, which cost more than the products on a few hundred rows."""
    u0, u1, u2 = u[:, 0], u[:, 1], u[:, 2]
    v0, v1, v2 = v[:, 0], v[:, 1], v[:, 2]
    out = np.empty((len(u), 3), dtype=np.result_type(u, v))
    out[:, 0] = u1 * v2 - u2 * v1
    out[:, 1] = u2 * v0 - u0 * v2
    out[:, 2] = u0 * v1 - u1 * v0
    return out


def _turned(bearings: np.ndarray, angle_rad: float) -> np.ndarray:
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    x, y = bearings[:, 0], bearings[:, 1]
    return np.stack([c * x - s * y, s * x + c * y, bearings[:, 2]], axis=1)


def _residuals(
    a: np.ndarray, b: np.ndarray, rotation_rad: float, direction_rad: float
) -> np.ndarray:
    """``a . (t x R b)`` for the unit horizontal ``t`` at ``direction_rad``."""
    normal = _cross(_turned(b, rotation_rad), a)  # t . (Rb x a) = a . (t x Rb)
    return math.cos(direction_rad) * normal[:, 0] + math.sin(direction_rad) * normal[:, 1]


def _direction_counts(
    a: np.ndarray,
    b: np.ndarray,
    rotation_rad: float,
    cos_d: np.ndarray,
    sin_d: np.ndarray,
    tolerance: float,
) -> np.ndarray:
    """For each direction of motion (``cos_d``, ``sin_d``: shape ``(D, 1)``), how many
    matched bearings fit the planar motion with ``rotation_rad`` within ``tolerance``."""
    normal = _cross(_turned(b, rotation_rad), a)
    counts: np.ndarray = (np.abs(cos_d * normal[:, 0] + sin_d * normal[:, 1]) < tolerance).sum(
        axis=1
    )
    return counts


#: Rotations x pairs :func:`_grid_counts` computes at once: a block of each
#: intermediate this large stays in the cache (all 242 rotations of 600 pairs at
#: once took twice the time), and few pairs still go in one block.
GRID_BLOCK = 16384


def _grid_counts(
    a: np.ndarray, b: np.ndarray, rotations: np.ndarray, direction_steps: int, tolerance: float
) -> np.ndarray:
    """For every rotation and each of ``direction_steps`` directions of motion over
    [0, pi), how many matched bearings fit the planar motion within ``tolerance``:
    ``(R, D)``, what :func:`_direction_counts` gives one rotation at a time.

    Not by trying every direction: for one pair at one rotation the residual is
    ``rho cos(d - psi)``, under the tolerance on one interval of directions (mod
    pi), so each pair adds one interval to a difference array and a cumulative sum
    counts them all. O(R M + R D) instead of O(R M D), a block of rotations at a time
    (:data:`GRID_BLOCK`); the counts do not depend on the blocks.
    """
    steps = direction_steps
    h = math.pi / steps
    width = 2 * steps + 2
    count = len(rotations)
    bx, by, bz = (np.ascontiguousarray(b[:, k]) for k in range(3))
    ax, ay, az = (np.ascontiguousarray(a[:, k]) for k in range(3))
    bz_ay, bz_ax = bz * ay, bz * ax
    cos_r, sin_r = np.cos(rotations), np.sin(rotations)
    diff = np.zeros(count * width, np.int64)
    everywhere_count = np.zeros(count, np.int64)
    block = max(1, GRID_BLOCK // max(1, len(a)))
    for lo in range(0, count, block):
        hi = min(count, lo + block)
        c, s = cos_r[lo:hi, None], sin_r[lo:hi, None]
        n_x = (s * bx + c * by) * az - bz_ay
        n_y = bz_ax - (c * bx - s * by) * az
        rho = np.hypot(n_x, n_y)
        psi = np.arctan2(n_y, n_x)
        everywhere = rho < tolerance
        # Where rho < tolerance the ratio is 1 and delta 0 (such pairs count everywhere).
        delta = np.arccos(tolerance / np.maximum(rho, tolerance))
        # |cos(d - psi)| < tol / rho  <=>  (d - psi) mod pi in (delta, pi - delta).
        # psi + delta lies in [-pi, 1.5 pi]: np.mod(., pi) there, to the last bit
        # (x - pi is exact on [pi, 2 pi]), without its general division.
        start = psi + delta
        start = np.where(start < 0.0, start + math.pi, start)
        start = np.where(start >= math.pi, start - math.pi, start)
        length = math.pi - 2.0 * delta
        first = np.floor(start / h).astype(np.int64) + 1
        last = np.ceil((start + length) / h).astype(np.int64) - 1
        ok = (last >= first) & ~everywhere
        rows = (np.arange(lo, hi) * width)[:, None]
        size = hi * width
        diff[:size] += np.bincount((rows + first)[ok], minlength=size)
        diff[:size] -= np.bincount((rows + last + 1)[ok], minlength=size)
        everywhere_count[lo:hi] = everywhere.sum(axis=1)
    extended = np.cumsum(diff.reshape(count, width), axis=1)
    counts: np.ndarray = extended[:, :steps] + extended[:, steps : 2 * steps]
    counts += everywhere_count[:, None]
    return counts


def _azimuth_peak(a: np.ndarray, b: np.ndarray) -> float:
    """The most common azimuth difference of matched bearings: the rotation, give or
    take the parallax (a histogram of 5-degree bins, smoothed over three)."""
    diff = np.arctan2(a[:, 1], a[:, 0]) - np.arctan2(b[:, 1], b[:, 0])
    bins = 72
    index = np.floor(np.mod(diff, 2.0 * math.pi) / (2.0 * math.pi) * bins).astype(np.int64)
    counts = np.bincount(index, minlength=bins)
    smooth = counts + np.roll(counts, 1) + np.roll(counts, -1)
    return wrap_angle_rad((int(np.argmax(smooth)) + 0.5) * 2.0 * math.pi / bins)


def _levelling(roll_rad: float, pitch_rad: float) -> np.ndarray:
    """The rotation taking bearings of a body rolled and pitched as given (the frame
    the camera sweeps in) into a level frame of the same heading: pitch about the
    left axis (nose down positive) after roll about the forward one."""
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    pitch = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    roll = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    matrix: np.ndarray = pitch @ roll
    return matrix


def _tilt_matrix(params: np.ndarray) -> np.ndarray:
    """The rotation of :func:`_tilted`'s ``params``: heading change after relative
    roll (about x) and pitch (about y)."""
    rotation, roll, pitch = params[:3]
    cz, sz = math.cos(rotation), math.sin(rotation)
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    turn = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    about_x = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    about_y = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    matrix: np.ndarray = turn @ about_x @ about_y
    return matrix


def _tilted_residuals(a: np.ndarray, b: np.ndarray, params: np.ndarray) -> np.ndarray:
    """``a . (t x R b)`` for the 3D rotation and the unit ``t`` (azimuth, elevation)
    of ``params`` = (rotation, roll, pitch, azimuth, elevation)."""
    azimuth, elevation = params[3], params[4]
    t = np.array(
        [
            math.cos(elevation) * math.cos(azimuth),
            math.cos(elevation) * math.sin(azimuth),
            math.sin(elevation),
        ]
    )
    normal: np.ndarray = _cross(b @ _tilt_matrix(params).T, a) @ t
    return normal


def _planar_residuals(a: np.ndarray, b: np.ndarray, params: np.ndarray) -> np.ndarray:
    """:func:`_residuals` for ``params`` = (rotation, direction)."""
    return _residuals(a, b, float(params[0]), float(params[1]))


def _gauss_newton(
    residuals: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
    a: np.ndarray,
    b: np.ndarray,
    params: np.ndarray,
    tolerance: float,
    iterations: int,
    needed: float,
) -> np.ndarray | None:
    """``iterations`` Gauss-Newton steps (forward-difference Jacobian) on the pairs
    whose residual is within ``tolerance``, chosen again each step; ``None`` as soon
    as fewer than ``needed`` are."""
    step = 1e-6
    for _ in range(iterations):
        all_residuals = residuals(a, b, params)
        inliers = np.abs(all_residuals) < tolerance
        if inliers.sum() < needed:
            return None
        a_in, b_in, r = a[inliers], b[inliers], all_residuals[inliers]
        jacobian = np.stack(
            [(residuals(a_in, b_in, params + e) - r) / step for e in np.eye(len(params)) * step],
            axis=1,
        )
        params = params + np.linalg.lstsq(jacobian, -r, rcond=None)[0]
    return params


def _refine_tilted(
    a: np.ndarray, b: np.ndarray, start: np.ndarray, config: TwoViewConfig, pixel_rad: float
) -> tuple[np.ndarray, int] | None:
    """Gauss-Newton from ``start`` on the inliers of ever tighter tolerances; the
    parameters and their inliers at the last tolerance, or ``None`` if too few."""
    params = start
    for tolerance_px in config.tilt_tolerances_px:
        tolerance = tolerance_px * pixel_rad
        iterations, needed = config.tilt_iterations, config.min_inliers
        refined = _gauss_newton(_tilted_residuals, a, b, params, tolerance, iterations, needed)
        if refined is None:
            return None
        params = refined
    final = config.tilt_tolerances_px[-1] * pixel_rad
    return params, int((np.abs(_tilted_residuals(a, b, params)) < final).sum())


def _tilted(
    a: np.ndarray,
    b: np.ndarray,
    fit: TwoViewFit,
    starts: list[tuple[float, float]],
    config: TwoViewConfig,
    pixel_rad: float,
) -> TwoViewFit:
    """``fit`` with the rotation and direction of the tilted refinement from the best
    of ``starts`` (rotation, direction); the planar fit if none converges to a
    plausible tilt with enough more inliers."""
    best: tuple[np.ndarray, int] | None = None
    for rotation, direction in starts:
        start = np.array([rotation, 0.0, 0.0, direction, 0.0])
        got = _refine_tilted(a, b, start, config, pixel_rad)
        if got is None or math.hypot(got[0][1], got[0][2]) > config.max_tilt_rad:
            continue
        if best is None or got[1] > best[1]:
            best = got
    if best is None or best[1] < config.tilt_min_gain * fit.inliers:
        return fit
    params = best[0]
    return replace(
        fit,
        rotation_rad=wrap_angle_rad(float(params[0])),
        direction_rad=float(np.mod(params[3], math.pi)),
        tilt_rad=float(math.hypot(params[1], params[2])),
    )
