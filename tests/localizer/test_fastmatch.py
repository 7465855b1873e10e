"""The fast path: properties on synthetic sweeps, and agreement with the reference."""

from __future__ import annotations

import math
import subprocess
import sys

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipemap.errors import LocalizerError
from pipemap.localizer import FastConfig, FastMatcher, ImageSet, pairwise_matches, wrap_angle_rad
from pipemap.localizer.fastmatch import prepare
from pipemap.localizer.prepared import _area_downsampled, _area_weights
from pipemap.localizer.similarity import reference_match
from tests.localizer.synthetic import expected_rotation_rad, panorama, sweep

# One fine-stage pixel (decimated by 4) of the synthetic sweeps, in radians, plus slack.
ROTATION_TOL_RAD = 4 * 2 * math.pi / (6 * 240) * 1.5


def _match(a: ImageSet, b: ImageSet, config: FastConfig | None = None):  # type: ignore[no-untyped-def]
    matcher = FastMatcher(config)
    matcher.add(matcher.prepare(b))
    return matcher.match(matcher.prepare(a))[0]


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), roll=st.integers(0, 5))
def test_cyclic_permutation_is_found_with_its_image_shift(seed: int, roll: int) -> None:
    a = sweep(panorama(seed))
    b = ImageSet(np.roll(a.images, -roll, axis=0), fov_rad=a.fov_rad)  # b[m] = a[m + roll]
    match = _match(a, b)
    assert match.image_shift == (-roll) % 6  # image j of a is image j - roll of b
    assert match.similarity > 0.99
    assert abs(match.pixel_shift) < 1.0
    assert match.refined


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), turn=st.integers(-700, 700))
def test_turned_sweep_gives_the_turn_as_rotation(seed: int, turn: int) -> None:
    pano = panorama(seed)
    a, b = sweep(pano), sweep(pano, turn=turn)
    match = _match(a, b)
    assert (
        abs(wrap_angle_rad(match.rotation_rad - expected_rotation_rad(turn, pano.shape[1])))
        < ROTATION_TOL_RAD
    )
    assert match.similarity > 0.6


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), turn=st.integers(-110, 110))
def test_horizontal_shift_within_an_image_step_is_the_pixel_shift(seed: int, turn: int) -> None:
    a, b = sweep(panorama(seed)), sweep(panorama(seed), turn=turn)
    match = _match(a, b)
    assert match.image_shift == 0
    assert match.pixel_shift == pytest.approx(-turn, abs=4.0)  # one fine-stage pixel


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), turn=st.integers(-700, 700))
def test_swapping_the_sets_mirrors_shift_and_rotation(seed: int, turn: int) -> None:
    # Algorithm 2 pairs image j of A with image j+k of B: the same pairs, read from
    # B, are offset N-k. The NCC normalizes the two roles differently, so the
    # similarity is close, not equal.
    pano = panorama(seed)
    a, b = sweep(pano), sweep(pano, turn=turn)
    ab, ba = _match(a, b), _match(b, a)
    assert (
        ba.image_shift == (6 - ab.image_shift) % 6
        or abs(wrap_angle_rad(ab.rotation_rad + ba.rotation_rad)) < ROTATION_TOL_RAD
    )
    assert abs(wrap_angle_rad(ab.rotation_rad + ba.rotation_rad)) < 2 * ROTATION_TOL_RAD
    assert ab.similarity == pytest.approx(ba.similarity, abs=0.05)


def test_different_panoramas_score_low() -> None:
    match = _match(sweep(panorama(1)), sweep(panorama(2)))
    assert match.similarity < 0.36


def test_database_returns_one_match_per_known_set_in_order() -> None:
    sets = [sweep(panorama(s)) for s in range(5)]
    matcher = FastMatcher()
    for s in sets:
        matcher.add(matcher.prepare(s))
    matches = matcher.match(matcher.prepare(sets[3]))
    assert len(matches) == 5
    assert max(range(5), key=lambda i: matches[i].similarity) == 3
    assert matches[3].similarity > 0.99
    # Two candidates are refined by default; the rest keep their screening match.
    assert sum(m.refined for m in matches) == 2


def test_empty_database_matches_nothing() -> None:
    matcher = FastMatcher()
    assert matcher.match(matcher.prepare(sweep(panorama(0)))) == []


def test_mismatched_sizes_are_refused() -> None:
    matcher = FastMatcher()
    matcher.add(matcher.prepare(sweep(panorama(0))))
    other = sweep(panorama(0, rows=160))
    with pytest.raises(LocalizerError):
        matcher.match(matcher.prepare(other))


def test_bad_config_is_refused() -> None:
    with pytest.raises(LocalizerError):
        FastConfig(fine_downsample=0)
    with pytest.raises(LocalizerError):
        FastConfig(coarse_dy_px=-1)


def test_prepare_is_deterministic() -> None:
    s = sweep(panorama(3))
    one, two = prepare(s, FastConfig()), prepare(s, FastConfig())
    assert np.array_equal(one.fine.spectrum, two.fine.spectrum)
    assert np.array_equal(one.image_rows, two.image_rows)


def test_pairwise_matches_cover_every_unordered_pair_in_order() -> None:
    sets = [sweep(panorama(s)) for s in range(4)]
    got = pairwise_matches(sets)
    assert list(got) == [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
    assert all(m.refined for m in got.values())


@pytest.mark.parametrize("every_offset", [False, True])
def test_a_pair_does_not_depend_on_the_other_sets(every_offset: bool) -> None:
    pano = panorama(11)
    sets = [sweep(pano), sweep(panorama(12)), sweep(pano, turn=200), sweep(panorama(13))]
    together = pairwise_matches(sets, every_offset=every_offset)
    for i, j in [(0, 2), (1, 3), (0, 3)]:
        alone = pairwise_matches([sets[i], sets[j]], every_offset=every_offset)[(0, 1)]
        assert together[(i, j)] == alone


def test_screened_matches_equal_best_offset_per_junction() -> None:
    from dataclasses import replace

    from pipemap.localizer import best_offset
    from pipemap.localizer.fastmatch import _offset_scores, _screened_matches

    rng = np.random.default_rng(4)
    peaks = rng.uniform(-0.2, 0.9, size=(7, 6, 6))
    peaks[3] = 0.5  # all offsets tie: the lowest offset wins, as in best_offset
    shifts = rng.uniform(-300, 300, size=(7, 6, 6))
    got = _screened_matches(_offset_scores(peaks), shifts, math.radians(80), 800)
    for i in range(7):
        want = replace(best_offset(peaks[i], shifts[i], math.radians(80), 800), refined=False)
        assert got[i].image_shift == want.image_shift
        assert got[i].similarity == pytest.approx(want.similarity, abs=1e-12)
        assert got[i].pixel_shift == pytest.approx(want.pixel_shift, abs=1e-9)
        assert got[i].rotation_rad == pytest.approx(want.rotation_rad, abs=1e-12)
        assert got[i].rotation_pinhole_rad == pytest.approx(want.rotation_pinhole_rad, abs=1e-12)
        assert not got[i].refined


@settings(max_examples=4, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    turn=st.integers(-700, 700),
    angle_a=st.floats(-0.6, 0.6),
    angle_b=st.floats(-0.6, 0.6),
)
def test_camera_angles_turn_the_rotation_into_a_heading_change(
    seed: int, turn: int, angle_a: float, angle_b: float
) -> None:
    # The cameras turned by `turn` columns; the robots' headings differ by that less
    # the difference of the cameras' angles to their headings.
    pano = panorama(seed)
    plain_a, plain_b = sweep(pano), sweep(pano, turn=turn)
    a = ImageSet(plain_a.images, fov_rad=plain_a.fov_rad, camera_angle_rad=angle_a)
    b = ImageSet(plain_b.images, fov_rad=plain_b.fov_rad, camera_angle_rad=angle_b)
    expected = wrap_angle_rad(expected_rotation_rad(turn, pano.shape[1]) + angle_a - angle_b)
    plain = _match(plain_a, plain_b)
    for match in (_match(a, b), reference_match(a, b)):
        assert abs(wrap_angle_rad(match.rotation_rad - expected)) < ROTATION_TOL_RAD
    # The images alone decide the match; the angles only relabel both rotations. (The
    # synthetic panorama is cylindrical, so the pinhole estimate is not checked here.)
    turned = _match(a, b)
    assert turned.similarity == plain.similarity
    assert turned.rotation_pinhole_rad == pytest.approx(
        wrap_angle_rad(plain.rotation_pinhole_rad + angle_a - angle_b), abs=1e-9
    )


def test_turned_match_keeps_everything_but_the_rotations() -> None:
    a = sweep(panorama(3))
    match = reference_match(a, a)
    turned = match.turned(3.0)
    assert turned.similarity == match.similarity and turned.image_shift == match.image_shift
    assert turned.rotation_rad == pytest.approx(wrap_angle_rad(match.rotation_rad + 3.0))
    assert -math.pi < turned.rotation_pinhole_rad <= math.pi
    assert match.turned(0.0) is match


def test_the_refinement_cache_holds_a_few_sets_whatever_the_database() -> None:
    """The spectra rebuilt for refinement are kept for the last few refined sets only:
    what they hold is counted (:meth:`FastMatcher.cache_bytes`), apart from what every
    known set keeps, and it stops growing at ``_FINE_CACHE`` sets."""
    from pipemap.localizer.fastmatch import _FINE_CACHE

    matcher = FastMatcher()
    for seed in range(_FINE_CACHE + 4):
        matcher.add(matcher.prepare(sweep(panorama(seed))))
    assert matcher.cache_bytes() == 0  # nothing refined yet
    one = None
    for seed in range(_FINE_CACHE + 4):
        matcher.match(matcher.prepare(sweep(panorama(seed), turn=seed)))
        if one is None:
            one = matcher.cache_bytes() / len(matcher._fine_cache)
    assert one is not None and one > 0
    assert len(matcher._fine_cache) == _FINE_CACHE
    assert matcher.cache_bytes() == pytest.approx(_FINE_CACHE * one)


def _unrounded_fine(image_set: ImageSet) -> np.ndarray:
    from pipemap.localizer.prepared import _fine_scaled

    return _fine_scaled(image_set.cropped(), FastConfig())


def test_a_lamp_lit_sweep_keeps_its_refinement_images_in_two_bytes_a_pixel() -> None:
    """Divided by its illumination, a sweep's quarter-scale images are float32
    quotients: they go on a 1/256 grey-level grid (moved by 1/512 at most) and are
    kept as uint16, and the query's own refinement uses the same rounded images that
    a known junction rebuilds from what it keeps."""
    from pipemap.localizer.illumination import normalised
    from pipemap.localizer.spectra import _fine_spectra

    lit = normalised(sweep(panorama(3)))
    prepared = prepare(lit, FastConfig())
    kept = prepared.fine_images
    assert kept is not None and kept.values.dtype == np.uint16 and kept.scale == 256.0
    unrounded = _unrounded_fine(lit)
    assert not np.array_equal(unrounded * 256.0, np.rint(unrounded * 256.0))  # off the grid
    assert np.array_equal(kept.images(), np.rint(unrounded * 256.0) / 256.0)
    assert np.abs(kept.images() - unrounded).max() <= 1.0 / 512.0
    rebuilt = _fine_spectra(kept.images(), lit.width)
    assert prepared.fine is not None
    assert np.array_equal(prepared.fine.spectrum, rebuilt.spectrum)


def test_box_means_of_8_bit_pixels_are_kept_exactly() -> None:
    """Evenly lit 8-bit sweeps (the paper's sets): the quarter-scale means of 16 pixels,
    exactly, in sixteenths of a grey level; no rounding."""
    eight_bit = ImageSet(np.rint(sweep(panorama(4)).images))
    kept = prepare(eight_bit, FastConfig()).fine_images
    assert kept is not None and kept.values.dtype == np.uint16 and kept.scale == 16.0
    assert np.array_equal(kept.images(), _unrounded_fine(eight_bit))


def test_images_beyond_0_to_255_keep_their_refinement_images_as_they_are() -> None:
    wide = ImageSet(sweep(panorama(5)).images * 4.0 - 100.0)
    kept = prepare(wide, FastConfig()).fine_images
    assert kept is not None and kept.values.dtype == np.float64
    assert np.array_equal(kept.images(), _unrounded_fine(wide))


def test_a_query_is_prepared_without_the_window_norms_only_a_searched_set_needs() -> None:
    """The refinement searches the known set's images, never the query's: a prepared
    set has no window norms (a fifth of its spectra's time); a database rebuilds
    them when it refines the set as a known one, and the match is the same as with
    norms computed up front. With ``baseline`` the set searches itself: kept."""
    from pipemap.localizer.spectra import _fine_spectra

    query = prepare(sweep(panorama(6), turn=9), FastConfig())
    assert query.fine is not None and query.fine.inv_window_norm is None
    with_baseline = prepare(sweep(panorama(6)), FastConfig(baseline=True))
    assert with_baseline.fine is not None and with_baseline.fine.inv_window_norm is not None
    matcher = FastMatcher()
    matcher.add(prepare(sweep(panorama(6)), FastConfig()))
    match = matcher.match(query)[0]
    rebuilt = matcher._refinable(0).fine
    assert rebuilt is not None and rebuilt.inv_window_norm is not None
    full = _fine_spectra(query.fine_images.images(), query.width_px)  # type: ignore[union-attr]
    assert full.inv_window_norm is not None
    assert np.array_equal(full.spectrum, query.fine.spectrum)
    assert match.refined and match.similarity > 0.9


@pytest.mark.parametrize(
    ("shape", "factor"),
    [((2, 200, 400), 16), ((2, 48, 96), 16), ((2, 37, 61), 16), ((2, 5, 7), 16), ((2, 60, 200), 8)],
)
def test_the_screening_images_are_opencvs_area_means(
    shape: tuple[int, int, int], factor: int
) -> None:
    # Whole and fractional factors (200 rows to 12, 37 to 2, 61 columns to 3): each
    # screening pixel is the mean of the area it covers, as OpenCV's INTER_AREA gives.
    images = np.random.default_rng(4).uniform(0.0, 255.0, shape).astype(np.float32)
    _, h, w = shape
    size = (max(w // factor, 2), max(h // factor, 2))
    expected = np.stack([cv2.resize(im, size, interpolation=cv2.INTER_AREA) for im in images])
    got = _area_downsampled(images, factor, factor)
    assert got.dtype == np.float64 and got.shape == expected.shape
    np.testing.assert_allclose(got, expected, rtol=0.0, atol=1e-4)
    np.testing.assert_allclose(_area_weights(h, size[1]).sum(axis=1), 1.0, rtol=1e-12)


def test_the_fft_module_is_loaded_with_the_matcher_not_at_the_first_sweep() -> None:
    """Loading the transforms, paid at the first sweep, was a robot's first decision's
    latency (0.2-0.3 s when it was scipy.fft's import). Importing the localizer does
    not load them (commands that never match start quickly); making a matcher does,
    and never imports scipy.fft (:mod:`localizer.transforms`)."""
    probe = (
        "import sys\n"
        "from pipemap.localizer import transforms\n"
        "from pipemap.localizer.fastmatch import FastMatcher\n"
        "before = transforms._pocketfft.cache_info().currsize\n"
        "FastMatcher()\n"
        "print(before, transforms._pocketfft.cache_info().currsize, 'scipy.fft' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["0", "1", "False"]


def test_a_known_junction_keeps_box_means_in_12_bits_and_gets_them_back_exactly() -> None:
    """The database packs the refinement images of an evenly lit 8-bit sweep (values
    below 4096) two in three bytes; a lamp-lit sweep's (on the 1/256 grid, up to
    65280) stay in two bytes. Either way the images it rebuilds spectra from are
    exactly the query's."""
    from pipemap.localizer.fastmatch import FastMatcher
    from pipemap.localizer.illumination import normalised

    for image_set, bytes_per_pixel in (
        (ImageSet(np.rint(sweep(panorama(4)).images)), 1.5),
        (normalised(sweep(panorama(3))), 2.0),
    ):
        prepared = prepare(image_set, FastConfig())
        matcher = FastMatcher()
        matcher.add(prepared)
        kept = matcher._sets[0].fine_images
        given = prepared.fine_images
        assert kept is not None and given is not None
        assert kept.values.nbytes == given.values.size * bytes_per_pixel
        assert np.array_equal(kept.images(), given.images())


def test_packing_in_12_bits_gives_back_an_odd_count_of_values_exactly() -> None:
    from pipemap.localizer.prepared import Compact

    values = (np.arange(15, dtype=np.uint16) * 273).reshape(3, 5)  # 0 .. 3822
    compact = Compact(values, 16.0)
    packed = compact.packed()
    assert packed.values.nbytes == 24 and packed.shape == (3, 5)
    assert np.array_equal(packed.images(), compact.images())
    assert Compact(values + 300, 16.0).packed().shape is None  # 4122: beyond 12 bits
