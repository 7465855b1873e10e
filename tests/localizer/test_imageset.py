"""Tests of :mod:`localizer.imageset`: validation up front, read-only float32 copies."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipemap.errors import LocalizerError, PipemapError
from pipemap.localizer.imageset import DEFAULT_FOV_RAD, DEFAULT_KEEP_TOP_FRACTION, ImageSet


def _images(n: int = 4, height: int = 16, width: int = 24, dtype: type = np.uint8) -> np.ndarray:
    rng = np.random.default_rng(7)
    return rng.integers(0, 255, size=(n, height, width)).astype(dtype)


# --- validation -----------------------------------------------------------------


def test_localizer_error_is_a_pipemap_error() -> None:
    assert issubclass(LocalizerError, PipemapError)


@pytest.mark.parametrize(
    "shape",
    [(16, 24), (24,), (2, 1, 16, 24), ()],
    ids=["2d", "1d", "4d", "scalar"],
)
def test_wrong_ndim_raises(shape: tuple[int, ...]) -> None:
    with pytest.raises(LocalizerError, match="shape"):
        ImageSet(np.zeros(shape, dtype=np.float32))


def test_zero_images_raises() -> None:
    with pytest.raises(LocalizerError, match="at least one image"):
        ImageSet(np.zeros((0, 16, 24), dtype=np.float32))


@pytest.mark.parametrize("height,width", [(3, 24), (16, 3), (3, 3), (0, 24), (16, 0)])
def test_too_small_images_raise(height: int, width: int) -> None:
    with pytest.raises(LocalizerError, match="too small"):
        ImageSet(np.zeros((2, height, width), dtype=np.float32))


def test_smallest_allowed_images_are_accepted() -> None:
    s = ImageSet(np.zeros((1, 4, 4), dtype=np.float32))
    assert (s.count, s.height, s.width, s.kept_rows) == (1, 4, 4, 2)


@pytest.mark.parametrize("dtype", [np.complex64, np.complex128])
def test_complex_dtype_raises(dtype: type) -> None:
    with pytest.raises(LocalizerError, match="real"):
        ImageSet(np.ones((2, 8, 8), dtype=dtype))


def test_non_numeric_dtype_raises() -> None:
    with pytest.raises(LocalizerError, match="real"):
        ImageSet(np.full((2, 8, 8), "a"))


@pytest.mark.parametrize("fov_rad", [0.0, -0.1, 2.0 * math.pi, 7.0, math.inf, math.nan], ids=str)
def test_fov_out_of_range_raises(fov_rad: float) -> None:
    with pytest.raises(LocalizerError, match="fov_rad"):
        ImageSet(_images(), fov_rad=fov_rad)


@pytest.mark.parametrize("fov_rad", [1e-6, math.radians(80.0), 2.0 * math.pi - 1e-6])
def test_fov_inside_range_is_accepted(fov_rad: float) -> None:
    assert ImageSet(_images(), fov_rad=fov_rad).fov_rad == fov_rad


@pytest.mark.parametrize("fraction", [0.0, -0.5, 1.0001, 2.0, math.nan], ids=str)
def test_keep_top_fraction_out_of_range_raises(fraction: float) -> None:
    with pytest.raises(LocalizerError, match="keep_top_fraction"):
        ImageSet(_images(), keep_top_fraction=fraction)


@pytest.mark.parametrize(
    "height,fraction",
    [(16, 0.05), (16, 1.0 / 16.0), (4, 0.25), (10, 0.14)],
)
def test_keeping_fewer_than_two_rows_raises(height: int, fraction: float) -> None:
    with pytest.raises(LocalizerError, match="fewer than 2 rows"):
        ImageSet(_images(height=height), keep_top_fraction=fraction)


def test_keeping_exactly_two_rows_is_accepted() -> None:
    s = ImageSet(_images(height=16), keep_top_fraction=2.0 / 16.0)
    assert s.kept_rows == 2
    assert s.cropped().shape == (4, 2, 24)


def test_from_images_with_differing_sizes_raises() -> None:
    with pytest.raises(LocalizerError, match="differ in size"):
        ImageSet.from_images([np.zeros((16, 24)), np.zeros((16, 25))])
    with pytest.raises(LocalizerError, match="differ in size"):
        ImageSet.from_images([np.zeros((16, 24)), np.zeros((16, 24)), np.zeros((17, 24))])


def test_from_images_with_no_images_raises() -> None:
    with pytest.raises(LocalizerError, match="at least one image"):
        ImageSet.from_images([])


def test_from_images_validates_like_the_constructor() -> None:
    with pytest.raises(LocalizerError, match="too small"):
        ImageSet.from_images([np.zeros((3, 24)), np.zeros((3, 24))])
    with pytest.raises(LocalizerError, match="fov_rad"):
        ImageSet.from_images([np.zeros((16, 24))], fov_rad=0.0)


def test_from_images_stacks_in_order() -> None:
    images = [np.full((8, 12), float(i)) for i in range(5)]
    s = ImageSet.from_images(images, fov_rad=1.0, keep_top_fraction=0.25)
    assert s.images.shape == (5, 8, 12)
    assert [float(s.images[i, 0, 0]) for i in range(5)] == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert (s.fov_rad, s.keep_top_fraction) == (1.0, 0.25)


def test_check_comparable_with_different_shapes_raises() -> None:
    base = ImageSet(_images(n=4, height=16, width=24))
    for other in (
        ImageSet(_images(n=5, height=16, width=24)),
        ImageSet(_images(n=4, height=18, width=24)),
        ImageSet(_images(n=4, height=16, width=26)),
    ):
        with pytest.raises(LocalizerError, match="differ in shape"):
            base.check_comparable(other)
        with pytest.raises(LocalizerError, match="differ in shape"):
            other.check_comparable(base)


def test_check_comparable_with_different_optics_raises() -> None:
    base = ImageSet(_images())
    with pytest.raises(LocalizerError, match="field of view"):
        base.check_comparable(ImageSet(_images(), fov_rad=1.0))
    with pytest.raises(LocalizerError, match="field of view"):
        base.check_comparable(ImageSet(_images(), keep_top_fraction=0.75))


def test_check_comparable_accepts_equal_geometry_with_other_content() -> None:
    a = ImageSet(_images(dtype=np.uint8))
    b = ImageSet(np.zeros((4, 16, 24), dtype=np.float64))
    assert a.check_comparable(b) is None
    assert b.check_comparable(a) is None


# --- the stored images ------------------------------------------------------------


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int32, np.float64, np.float16])
def test_images_become_float32_with_equal_values(dtype: type) -> None:
    source = _images(dtype=dtype)
    s = ImageSet(source)
    assert s.images.dtype == np.float32
    np.testing.assert_array_equal(s.images, source.astype(np.float32))


def test_images_are_a_copy_of_the_source() -> None:
    source = _images(dtype=np.float32)
    s = ImageSet(source)
    assert not np.shares_memory(s.images, source)
    before = s.images.copy()
    source[...] = 0
    source[0, 0, 0] = 123
    np.testing.assert_array_equal(s.images, before)


def test_float32_source_is_still_copied() -> None:
    source = np.ones((2, 8, 8), dtype=np.float32)
    s = ImageSet(source)
    source += 1.0
    assert float(s.images.max()) == 1.0


def test_from_images_copies_too() -> None:
    sources = [np.ones((8, 8), dtype=np.float32) for _ in range(3)]
    s = ImageSet.from_images(sources)
    sources[1][:] = 9.0
    assert float(s.images.max()) == 1.0


def test_images_are_read_only() -> None:
    s = ImageSet(_images())
    assert not s.images.flags.writeable
    with pytest.raises(ValueError):
        s.images[0, 0, 0] = 1.0
    with pytest.raises(ValueError):
        s.images += 1.0
    with pytest.raises(ValueError):
        np.copyto(s.images, 0.0)


def test_cropped_is_read_only() -> None:
    s = ImageSet(_images())
    with pytest.raises(ValueError):
        s.cropped()[0, 0, 0] = 1.0


def test_image_set_attributes_cannot_be_rebound() -> None:
    s = ImageSet(_images())
    with pytest.raises(AttributeError):
        s.images = np.zeros((4, 16, 24))  # type: ignore[misc]
    with pytest.raises(AttributeError):
        s.fov_rad = 1.0  # type: ignore[misc]


def test_nested_list_input_is_accepted() -> None:
    # __post_init__ runs np.asarray on its input, so array-likes are meant to work;
    # a valid nested list must either build a set or raise LocalizerError.
    source = _images(n=2, height=8, width=8)
    s = ImageSet(source.tolist())  # type: ignore[arg-type]
    np.testing.assert_array_equal(s.images, source.astype(np.float32))


# --- derived values -----------------------------------------------------------------


def test_defaults_are_the_papers_camera() -> None:
    s = ImageSet(_images())
    assert pytest.approx(math.radians(80.0)) == DEFAULT_FOV_RAD
    assert DEFAULT_KEEP_TOP_FRACTION == 0.5
    assert s.fov_rad == DEFAULT_FOV_RAD
    assert s.keep_top_fraction == DEFAULT_KEEP_TOP_FRACTION


@pytest.mark.parametrize(
    "n,height,width,fraction,kept",
    [
        (6, 128, 192, 0.5, 64),
        (12, 120, 160, 0.5, 60),
        (1, 16, 24, 1.0, 16),
        (3, 10, 8, 0.3, 3),
        (2, 100, 4, 0.25, 25),
    ],
)
def test_count_height_width_kept_rows_step(
    n: int, height: int, width: int, fraction: float, kept: int
) -> None:
    s = ImageSet(np.zeros((n, height, width)), keep_top_fraction=fraction)
    assert (s.count, s.height, s.width) == (n, height, width)
    assert s.kept_rows == kept
    assert s.step_rad == pytest.approx(2.0 * math.pi / n)
    assert s.step_rad * s.count == pytest.approx(2.0 * math.pi)


def test_cropped_is_the_top_rows() -> None:
    source = _images(n=3, height=20, width=10, dtype=np.float32)
    s = ImageSet(source, keep_top_fraction=0.5)
    cropped = s.cropped()
    assert cropped.shape == (3, 10, 10)
    assert cropped.dtype == np.float32
    np.testing.assert_array_equal(cropped, source[:, :10, :])


def test_cropped_with_full_fraction_is_everything() -> None:
    source = _images(n=2, height=9, width=11)
    s = ImageSet(source, keep_top_fraction=1.0)
    assert s.cropped().shape == (2, 9, 11)
    np.testing.assert_array_equal(s.cropped(), s.images)


@pytest.mark.parametrize("angle", [math.nan, math.inf, -math.inf])
def test_camera_angle_must_be_finite(angle: float) -> None:
    with pytest.raises(LocalizerError, match="camera_angle_rad"):
        ImageSet(np.zeros((6, 8, 8)), camera_angle_rad=angle)


def test_camera_angle_defaults_to_straight_ahead_and_is_kept() -> None:
    images = [np.zeros((8, 8))] * 6
    assert ImageSet.from_images(images).camera_angle_rad == 0.0
    assert ImageSet.from_images(images, camera_angle_rad=0.5).camera_angle_rad == 0.5
