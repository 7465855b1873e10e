"""The reference similarity (Algorithm 2) on small synthetic images."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipemap.localizer import ImageSet, best_offset, ncc_same, pair_peak, reference_match
from pipemap.localizer.similarity import (
    _correlate_same,
    relative_rotation_rad,
    window_sums,
    wrap_angle_rad,
)


def _texture(rng: np.random.Generator, shape: tuple[int, int]) -> np.ndarray:
    # Smooth enough that a shift of one pixel keeps most of the correlation.
    base = rng.normal(size=(shape[0] + 4, shape[1] + 4))
    kernel = np.ones(3) / 3.0
    base = np.apply_along_axis(lambda r: np.convolve(r, kernel, mode="same"), 1, base)
    base = np.apply_along_axis(lambda c: np.convolve(c, kernel, mode="same"), 0, base)
    return base[2:-2, 2:-2] * 40.0 + 128.0


def test_window_sums_match_brute_force() -> None:
    rng = np.random.default_rng(0)
    values = rng.normal(size=(5, 7))
    dys = np.array([-3, -1, 0, 2, 4])
    dxs = np.array([-6, -2, 0, 3, 6])
    got = window_sums(values, dys, dxs)
    padded = np.zeros((5 + 20, 7 + 20))
    padded[10:15, 10:17] = values
    for iy, dy in enumerate(dys):
        for ix, dx in enumerate(dxs):
            want = padded[10 + dy : 15 + dy, 10 + dx : 17 + dx].sum()
            assert got[iy, ix] == pytest.approx(want, abs=1e-12)


@pytest.mark.parametrize("shape", [(5, 7), (6, 8), (1, 9), (4, 3)])
def test_correlation_is_the_sum_over_every_same_shift(shape: tuple[int, int]) -> None:
    # Entry [iy, ix] sums template[y, x] * image[y + dy, x + dx], image zero outside,
    # for dy = iy - h//2 and dx = ix - w//2: checked against the sum itself.
    rng = np.random.default_rng(4)
    h, w = shape
    image, template = rng.normal(size=shape), rng.normal(size=shape)
    got = _correlate_same(image, template)
    assert got.shape == shape
    padded = np.zeros((3 * h, 3 * w))
    padded[h : 2 * h, w : 2 * w] = image
    for iy in range(h):
        for ix in range(w):
            dy, dx = iy - h // 2, ix - w // 2
            window = padded[h + dy : 2 * h + dy, w + dx : 2 * w + dx]
            assert got[iy, ix] == pytest.approx(float(np.sum(template * window)), abs=1e-9)


def test_window_sums_accept_a_stack() -> None:
    rng = np.random.default_rng(1)
    stack = rng.normal(size=(3, 6, 8))
    dys, dxs = np.arange(6) - 3, np.arange(8) - 4
    batched = window_sums(stack, dys, dxs)
    for i in range(3):
        np.testing.assert_allclose(batched[i], window_sums(stack[i], dys, dxs), atol=1e-12)


def test_identical_images_peak_at_one_with_no_shift() -> None:
    image = _texture(np.random.default_rng(2), (40, 60))
    ncc = ncc_same(image, image)
    assert ncc.max() == pytest.approx(1.0, abs=1e-9)
    peak = pair_peak(image, image)
    assert (peak.dx_px, peak.dy_px) == (0.0, 0.0)
    assert np.all(ncc <= 1.0) and np.all(ncc >= -1.0)


@pytest.mark.parametrize(("dy", "dx"), [(0, 7), (3, -11), (-5, 0), (2, 19)])
def test_peak_is_at_the_shift_of_the_content(dy: int, dx: int) -> None:
    # Two views of one scene: image[y + dy, x + dx] == template[y, x], and new
    # content where the view moved, as when a camera turns.
    scene = _texture(np.random.default_rng(3), (80, 100))
    template = scene[20:60, 20:80]
    image = scene[20 - dy : 60 - dy, 20 - dx : 80 - dx]
    peak = pair_peak(template, image)
    assert (peak.dy_px, peak.dx_px) == (dy, dx)
    # The whole template counts in the normalization, so partial overlap lowers the
    # peak below 1: the paper's definition favours views that overlap fully.
    overlap = (1 - abs(dy) / 40) * (1 - abs(dx) / 60)
    assert overlap - 0.05 < peak.ncc < 1.0


def test_flat_image_gives_zero_not_nan() -> None:
    template = _texture(np.random.default_rng(4), (20, 30))
    flat = np.full((20, 30), 77.0)
    ncc = ncc_same(template, flat)
    assert np.all(np.isfinite(ncc))
    assert np.all(ncc == 0.0)


def test_best_offset_averages_pairs_of_each_offset() -> None:
    n = 6
    peaks = np.full((n, n), 0.1)
    shifts = np.zeros((n, n))
    for j in range(n):  # offset 2 holds the matching pairs
        peaks[j, (j + 2) % n] = 0.8
        shifts[j, (j + 2) % n] = 10.0 + j
    match = best_offset(peaks, shifts, math.radians(80), 800)
    assert match.image_shift == 2
    assert match.similarity == pytest.approx(0.8)
    assert match.pixel_shift == pytest.approx(12.5)
    expected = 2 * 2 * math.pi / 6 + 12.5 * math.radians(80) / 800
    assert match.rotation_rad == pytest.approx(expected)


def test_best_offset_tie_goes_to_the_lowest_offset() -> None:
    peaks = np.full((4, 4), 0.5)
    assert best_offset(peaks, np.zeros((4, 4)), 1.0, 100).image_shift == 0


def test_wrap_angle_range() -> None:
    assert wrap_angle_rad(math.pi) == math.pi
    assert wrap_angle_rad(-math.pi) == math.pi
    assert wrap_angle_rad(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert wrap_angle_rad(-0.25) == pytest.approx(-0.25)
    assert relative_rotation_rad(5, 0.0, 6, 1.0, 100) == pytest.approx(-math.pi / 3)


def test_reference_finds_a_cyclic_permutation() -> None:
    rng = np.random.default_rng(5)
    images = np.stack([_texture(rng, (48, 64)) for _ in range(6)])
    a = ImageSet(images)
    b = ImageSet(np.roll(images, -1, axis=0))  # image m of b is image m+1 of a
    match = reference_match(a, b)
    # Image j of a is image j-1 of b: offset k = N - 1.
    assert match.image_shift == 5
    assert match.similarity == pytest.approx(1.0, abs=1e-9)
    assert match.pixel_shift == 0.0
