"""The coarse grid of the two-view fit: the interval counting is the direct count."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipemap.localizer import epipolar


def _bearings(rng: np.random.Generator, count: int) -> np.ndarray:
    rays = rng.normal(size=(count, 3))
    return rays / np.linalg.norm(rays, axis=1, keepdims=True)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_grid_counts_what_each_direction_counts(seed: int) -> None:
    """Every cell of the grid is the number of pairs within the tolerance at that
    rotation and direction, counted directly."""
    rng = np.random.default_rng(seed)
    a, b = _bearings(rng, 300), _bearings(rng, 300)
    rotations = rng.uniform(-4.0, 4.0, size=70)  # more than a block, not a multiple
    steps, tolerance = 90, 0.01
    grid = epipolar._grid_counts(a, b, rotations, steps, tolerance)
    directions = np.linspace(0.0, math.pi, steps, endpoint=False)
    cos_d, sin_d = np.cos(directions)[:, None], np.sin(directions)[:, None]
    for row, rotation in zip(grid, rotations, strict=True):
        direct = epipolar._direction_counts(a, b, float(rotation), cos_d, sin_d, tolerance)
        np.testing.assert_array_equal(row, direct)


def test_blocks_of_rotations_do_not_change_the_counts(monkeypatch: pytest.MonkeyPatch) -> None:
    """The rotations are counted a block at a time: one at a time, or all at once, the
    grid is the same to the last count."""
    rng = np.random.default_rng(4)
    a, b = _bearings(rng, 500), _bearings(rng, 500)
    rotations = np.linspace(-0.3, 0.3, 121) + 0.7
    tolerance = 0.004  # some pairs within it everywhere: rho below it
    counts = []
    for block in (1, 7 * 500, epipolar.GRID_BLOCK, 10**9):  # 1 rotation, 7, ..., all
        monkeypatch.setattr(epipolar, "GRID_BLOCK", block)
        counts.append(epipolar._grid_counts(a, b, rotations, 90, tolerance))
    for other in counts[1:]:
        np.testing.assert_array_equal(other, counts[0])
    assert counts[0].max() > 0
