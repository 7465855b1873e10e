"""Two-view geometry: keypoint bearings and the motion fit between two sweeps."""

from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from pipemap.localizer import twoview
from pipemap.localizer.epipolar import _levelling
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.keymatch import _matches
from pipemap.localizer.similarity import wrap_angle_rad
from pipemap.localizer.twoview import (
    SweepFeatures,
    TwoViewConfig,
    fit_two_view,
    overlapping_images,
    stored_features,
    sweep_features,
)

PIXEL_RAD = 1.0 / 240.0  # about a 400 px image with an 80 degree field of view


def _scene(rng: np.random.Generator, count: int) -> np.ndarray:
    """Points on the walls of a pipe junction around the origin: most 8-15 cm away
    (the walls), some 0.5-2 m (down the pipes), between 10 cm below and 10 cm above."""
    azimuth = rng.uniform(-math.pi, math.pi, count)
    near = rng.random(count) < 0.8
    distance = np.where(near, rng.uniform(0.08, 0.15, count), rng.uniform(0.5, 2.0, count))
    height = rng.uniform(-0.1, 0.1, count)
    return np.stack([distance * np.cos(azimuth), distance * np.sin(azimuth), height], axis=1)


def _bearings(points: np.ndarray, position: np.ndarray, heading_rad: float) -> np.ndarray:
    """Unit bearings of ``points`` from a robot at ``position`` facing ``heading_rad``."""
    rel = points - position
    c, s = math.cos(-heading_rad), math.sin(-heading_rad)
    local = np.stack([c * rel[:, 0] - s * rel[:, 1], s * rel[:, 0] + c * rel[:, 1], rel[:, 2]], 1)
    noisy = local / np.linalg.norm(local, axis=1, keepdims=True)
    return noisy


def _pair(
    rng: np.random.Generator,
    query_heading: float,
    known_heading: float,
    offset_m: tuple[float, float],
    outliers: int = 0,
    count: int = 600,
    noise_rad: float = 0.3 * PIXEL_RAD,
) -> tuple[SweepFeatures, SweepFeatures]:
    """The same scene seen from the centre (known) and from ``offset_m`` (query), with
    one random descriptor per point, bearing noise and ``outliers`` random keypoints."""
    points = _scene(rng, count)
    descriptors = rng.integers(0, 256, (count, 32), dtype=np.uint8)
    known = _bearings(points, np.zeros(3), known_heading)
    query = _bearings(points, np.array([*offset_m, 0.0]), query_heading)
    query = query + rng.normal(0.0, noise_rad, query.shape)
    query /= np.linalg.norm(query, axis=1, keepdims=True)
    if outliers:
        junk = rng.normal(size=(outliers, 3))
        query = np.concatenate([query, junk / np.linalg.norm(junk, axis=1, keepdims=True)])
        descriptors_q = np.concatenate(
            [descriptors, rng.integers(0, 256, (outliers, 32), dtype=np.uint8)]
        )
    else:
        descriptors_q = descriptors
    return SweepFeatures(query, descriptors_q, PIXEL_RAD), SweepFeatures(
        known, descriptors, PIXEL_RAD
    )


@pytest.mark.parametrize(
    ("query_heading", "known_heading", "offset_m"),
    [
        (0.0, 1.0, (0.03, 0.0)),
        (2.5, -2.0, (-0.02, 0.025)),
        (-1.0, 0.4, (0.0, -0.035)),
    ],
)
def test_rotation_is_found_through_parallax(
    query_heading: float, known_heading: float, offset_m: tuple[float, float]
) -> None:
    """3 cm off centre, walls 8-15 cm away: the azimuths of matched points differ from
    the rotation by up to 0.4 rad, yet the fit recovers it to a fraction of a pixel."""
    rng = np.random.default_rng(7)
    query, known = _pair(rng, query_heading, known_heading, offset_m, outliers=200)
    fit = fit_two_view(query, known)
    assert fit is not None
    true = wrap_angle_rad(known_heading - query_heading)
    assert abs(wrap_angle_rad(fit.rotation_rad - true)) < 0.5 * PIXEL_RAD
    assert fit.inliers >= 570  # of the 600 true matches
    assert fit.matches >= 600
    # The motion's direction in the query's frame (modulo pi).
    direction = math.atan2(offset_m[1], offset_m[0]) - query_heading
    assert abs(math.remainder(fit.direction_rad - direction, math.pi)) < 0.05


def test_parallax_is_large_in_these_scenes() -> None:
    """The premise of the test above: the mean azimuth shift alone misses the turn."""
    rng = np.random.default_rng(7)
    query, known = _pair(rng, 0.0, 1.0, (0.03, 0.0), noise_rad=0.0)
    shift = np.arctan2(query.bearings[:, 1], query.bearings[:, 0]) - np.arctan2(
        known.bearings[:, 1], known.bearings[:, 0]
    )
    parallax = np.abs(np.remainder(shift - 1.0 + math.pi, 2 * math.pi) - math.pi)
    assert parallax.max() > 0.3


def test_pure_rotation_is_found() -> None:
    """Both sweeps from one spot: no motion to find, the rotation is still fixed by
    the points above and below the horizon."""
    rng = np.random.default_rng(3)
    query, known = _pair(rng, 0.3, -1.2, (0.0, 0.0), outliers=100)
    fit = fit_two_view(query, known)
    assert fit is not None
    assert abs(wrap_angle_rad(fit.rotation_rad - (-1.5))) < 0.5 * PIXEL_RAD


def test_a_wrong_guess_does_not_hide_the_rotation() -> None:
    rng = np.random.default_rng(5)
    query, known = _pair(rng, 0.0, 2.0, (0.03, 0.01))
    fit = fit_two_view(query, known, guess_rad=-1.0)
    assert fit is not None
    assert abs(wrap_angle_rad(fit.rotation_rad - 2.0)) < 0.5 * PIXEL_RAD


def test_different_places_give_no_fit() -> None:
    """Keypoints of two unrelated scenes (their descriptors happen to match) fit no
    single motion."""
    rng = np.random.default_rng(11)
    query, _ = _pair(rng, 0.0, 0.0, (0.0, 0.0))
    _, other = _pair(rng, 0.0, 0.0, (0.0, 0.0))
    same_descriptors = SweepFeatures(other.bearings, query.descriptors, PIXEL_RAD)
    assert fit_two_view(query, same_descriptors) is None


def test_too_few_matches_give_no_fit() -> None:
    rng = np.random.default_rng(1)
    query, known = _pair(rng, 0.0, 0.5, (0.02, 0.0), count=8)
    assert fit_two_view(query, known, TwoViewConfig(min_inliers=12)) is None
    empty = SweepFeatures(np.zeros((0, 3)), np.zeros((0, 32), np.uint8), PIXEL_RAD)
    assert fit_two_view(empty, known) is None


def test_turned_fit_adds_the_angle() -> None:
    rng = np.random.default_rng(2)
    query, known = _pair(rng, 0.0, 3.0, (0.01, 0.0))
    fit = fit_two_view(query, known)
    assert fit is not None
    assert fit.turned(0.5).rotation_rad == pytest.approx(wrap_angle_rad(fit.rotation_rad + 0.5))
    assert fit.turned(0.5).inliers == fit.inliers


def _textured(seed: int, size: int = 200) -> np.ndarray:
    rng = np.random.default_rng(seed)
    noise = rng.uniform(0, 255, (size // 8, size // 8)).astype(np.float32)
    return cv2.resize(noise, (size, size), interpolation=cv2.INTER_CUBIC)


def test_keypoints_lie_in_their_images_field_of_view() -> None:
    """Image j looks ``camera_angle - j * 60 deg`` from the heading; each keypoint's
    bearing is within half the field of view of that, and in the kept (top) rows."""
    fov = math.radians(80.0)
    images = np.stack([_textured(j) for j in range(6)])
    image_set = ImageSet(images, fov_rad=fov, keep_top_fraction=0.5, camera_angle_rad=0.4)
    features = sweep_features(image_set)
    assert len(features) > 100
    assert features.pixel_rad == pytest.approx(math.tan(fov / 2) / 100.0)
    assert np.allclose(np.linalg.norm(features.bearings, axis=1), 1.0)
    azimuth = np.arctan2(features.bearings[:, 1], features.bearings[:, 0])
    centres = 0.4 - np.arange(6) * math.pi / 3
    off_axis = np.abs(np.remainder(azimuth[:, None] - centres + math.pi, 2 * math.pi) - math.pi)
    assert np.all(off_axis.min(axis=1) <= fov / 2)
    assert np.all(features.bearings[:, 2] > -1e-9)  # the top half only: at or above the horizon


@pytest.mark.parametrize("size", [200, 400])
def test_the_keypoints_an_image_keeps_depend_on_the_width_orb_sees(size: int) -> None:
    """An image ORB sees at its own size (200 px) keeps up to ``keypoints_per_image``
    keypoints; a wider one (400 px) is reduced first and keeps up to
    ``reduced_keypoints_per_image``, whatever ``keypoints_per_image`` says."""
    images = np.stack([_textured(j, size) for j in range(6)])
    image_set = ImageSet(images, fov_rad=math.radians(80.0), keep_top_fraction=0.5)
    config = TwoViewConfig()
    kept = {
        n: np.bincount(
            stored_features(image_set, replace(config, keypoints_per_image=n)).image,
            minlength=6,
        )
        for n in (150, config.keypoints_per_image)
    }
    if size <= config.detect_width_px:
        assert kept[150].max() <= 150 < kept[config.keypoints_per_image].min()
    else:
        assert np.array_equal(kept[150], kept[config.keypoints_per_image])
        assert kept[150].max() <= config.reduced_keypoints_per_image


@pytest.mark.parametrize("size", [200, 400])
def test_the_fast_threshold_depends_on_the_width_orb_sees(size: int) -> None:
    """ORB's FAST threshold is ``fast_threshold`` for an image seen at its own size
    and ``reduced_fast_threshold`` for a reduced one; each is ignored on the other
    path. A higher threshold keeps fewer, clearer corners."""
    images = np.stack([_textured(j, size) for j in range(6)])
    image_set = ImageSet(images, fov_rad=math.radians(80.0), keep_top_fraction=0.5)
    config = TwoViewConfig()
    own, reduced = ("fast_threshold", "reduced_fast_threshold")[:: 1 if size <= 200 else -1]
    count = {
        (name, value): len(stored_features(image_set, replace(config, **{name: value})))
        for name in (own, reduced)
        for value in (5, 40)
    }
    assert count[(own, 40)] < count[(own, 5)]
    assert count[(reduced, 40)] == count[(reduced, 5)]


def test_camera_angle_turns_every_bearing() -> None:
    images = np.stack([_textured(10 + j) for j in range(6)])
    a = sweep_features(ImageSet(images, camera_angle_rad=0.0))
    b = sweep_features(ImageSet(images, camera_angle_rad=0.7))
    turn = np.arctan2(b.bearings[:, 1], b.bearings[:, 0]) - np.arctan2(
        a.bearings[:, 1], a.bearings[:, 0]
    )
    assert np.allclose(np.remainder(turn - 0.7 + math.pi, 2 * math.pi) - math.pi, 0.0, atol=1e-9)
    assert np.array_equal(a.descriptors, b.descriptors)


def test_a_sweep_matches_itself_turned() -> None:
    """The same images with the camera started 60 degrees on: the fit's rotation is
    the 60 degrees, from real ORB keypoints."""
    images = np.stack([_textured(20 + j) for j in range(6)])
    query = sweep_features(ImageSet(images, camera_angle_rad=0.0))
    known = sweep_features(ImageSet(np.roll(images, 1, axis=0), camera_angle_rad=math.pi / 3))
    fit = fit_two_view(query, known)
    assert fit is not None
    assert abs(wrap_angle_rad(fit.rotation_rad)) < 1e-6
    assert fit.inliers == fit.matches


def _leaned(features: SweepFeatures, roll_rad: float, pitch_rad: float) -> SweepFeatures:
    """The bearings as a robot standing ``roll_rad`` and ``pitch_rad`` off level sees
    them (its body frame turned by roll about x, then pitch about y)."""
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    about_x = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    about_y = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    body = about_x @ about_y  # body axes in the level frame
    return SweepFeatures(features.bearings @ body, features.descriptors, features.pixel_rad)


@pytest.mark.parametrize(("roll_rad", "pitch_rad"), [(0.0, 0.05), (0.03, -0.04)])
def test_a_sweep_off_level_still_gives_the_rotation(roll_rad: float, pitch_rad: float) -> None:
    """A robot 0.05 rad off level, as in the paper's own image sets: the planar model
    alone is thrown off; with the relative tilt free the rotation is within a pixel."""
    rng = np.random.default_rng(11)
    query, known = _pair(rng, 0.4, -0.9, (0.025, -0.01), outliers=150)
    query = _leaned(query, roll_rad, pitch_rad)
    true = wrap_angle_rad(-0.9 - 0.4)
    planar = fit_two_view(query, known, TwoViewConfig(tilt=False))
    assert planar is not None
    assert planar.tilt_rad == 0.0
    assert abs(wrap_angle_rad(planar.rotation_rad - true)) > 2 * PIXEL_RAD
    fit = fit_two_view(query, known)
    assert fit is not None
    assert abs(wrap_angle_rad(fit.rotation_rad - true)) < PIXEL_RAD
    assert fit.tilt_rad == pytest.approx(math.hypot(roll_rad, pitch_rad), abs=0.005)
    # The check that decides known or new counts the planar fit's inliers.
    assert fit.inliers == planar.inliers


@pytest.mark.parametrize(("roll_rad", "pitch_rad"), [(0.05, 0.0), (0.0, -0.04)])
def test_the_imu_reading_levels_the_bearings(roll_rad: float, pitch_rad: float) -> None:
    """What a camera on a body leaning as the IMU reads sees (:func:`_leaned`), levelled
    by that reading, is what a level camera sees; ``imu_level`` off leaves it be."""
    images = np.stack([_textured(30 + j) for j in range(6)])
    level = sweep_features(ImageSet(images, camera_angle_rad=0.3))
    seen = _leaned(level, roll_rad, pitch_rad).bearings
    assert np.allclose(seen @ _levelling(roll_rad, pitch_rad).T, level.bearings, atol=1e-12)
    # A sweep told the reading levels its bearings so.
    told = ImageSet(images, camera_angle_rad=0.3, imu_tilt_rad=(roll_rad, pitch_rad))
    levelled = sweep_features(told).bearings
    assert np.allclose(levelled, level.bearings @ _levelling(roll_rad, pitch_rad).T, atol=1e-12)
    assert not np.allclose(levelled, level.bearings, atol=1e-3)
    untold = sweep_features(told, TwoViewConfig(imu_level=False)).bearings
    assert np.array_equal(untold, level.bearings)


def test_sweeps_both_levelled_by_their_imus_skip_the_tilt_refinement(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Left with only the IMU's error there is no tilt to find: the refinement is made
    only when a sweep has no reading."""
    from pipemap.localizer import twoview

    calls: list[int] = []
    real = twoview._tilted

    def spy(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(twoview, "_tilted", spy)
    query, known = _pair(np.random.default_rng(13), 1.1, 0.2, (-0.03, 0.015), outliers=150)
    levelled = [replace(f, levelled=True) for f in (query, known)]
    assert fit_two_view(*levelled) is not None and calls == []
    assert fit_two_view(levelled[0], known) is not None and calls == [1]
    assert fit_two_view(query, known) is not None and calls == [1, 1]
    # Real sweeps: levelled exactly when told a reading (a level one included).
    images = np.stack([_textured(50 + j) for j in range(6)])
    assert sweep_features(ImageSet(images, imu_tilt_rad=(0.0, 0.0))).levelled
    assert not sweep_features(ImageSet(images)).levelled
    told = ImageSet(images, imu_tilt_rad=(0.02, 0.0))
    assert not sweep_features(told, TwoViewConfig(imu_level=False)).levelled


def test_a_level_reading_changes_no_bearing() -> None:
    images = np.stack([_textured(40 + j) for j in range(6)])
    plain = sweep_features(ImageSet(images)).bearings
    assert np.array_equal(sweep_features(ImageSet(images, imu_tilt_rad=(0.0, 0.0))).bearings, plain)


def test_an_impossible_imu_reading_is_refused() -> None:
    from pipemap.errors import LocalizerError

    with pytest.raises(LocalizerError, match="imu_tilt_rad"):
        ImageSet(np.zeros((6, 16, 16)), imu_tilt_rad=(2.0, 0.0))


def test_level_sweeps_keep_the_planar_fit() -> None:
    """Three more unknowns fit level sweeps no better: the planar fit stands as it is."""
    rng = np.random.default_rng(13)
    query, known = _pair(rng, 1.1, 0.2, (-0.03, 0.015), outliers=150)
    planar = fit_two_view(query, known, TwoViewConfig(tilt=False))
    fit = fit_two_view(query, known)
    assert planar is not None
    assert fit == planar


def _sweep_layout(count: int, fov_rad: float) -> SweepFeatures:
    """Features of ``count`` images (one keypoint each) that say where they look."""
    looks = -np.arange(count) * 2.0 * math.pi / count
    return SweepFeatures(
        np.zeros((count, 3)),
        np.zeros((count, 32), np.uint8),
        PIXEL_RAD,
        np.arange(count, dtype=np.uint8),
        looks,
        fov_rad,
    )


def test_overlapping_images_are_the_neighbours_the_rotation_brings() -> None:
    six = _sweep_layout(6, math.radians(80.0))
    # Lined up: each image reaches its own and its two neighbours (60 degrees off),
    # not those 120 degrees off.
    aligned = overlapping_images(six, six, 0.0, 0.3)
    assert aligned is not None
    assert [sorted(row.tolist()) for row in aligned] == [
        sorted([(k - 1) % 6, k, (k + 1) % 6]) for k in range(6)
    ]
    # Turned by one image step: image k of the known sweep looks where the query's
    # image k - 1 does (the camera steps clockwise).
    turned = overlapping_images(six, six, 2.0 * math.pi / 6, 0.3)
    assert turned is not None
    assert [sorted(row.tolist()) for row in turned] == [
        sorted([(k - 2) % 6, (k - 1) % 6, k]) for k in range(6)
    ]
    unplaced = SweepFeatures(six.bearings, six.descriptors, PIXEL_RAD)
    assert overlapping_images(unplaced, six, 0.0, 0.3) is None


def test_the_overlap_margin_widens_the_images_compared() -> None:
    """Half an image step off (30 degrees), each image looks between two of the other
    sweep's, 30 degrees from each and 90 from the next: within the field of view (80
    degrees) alone, two images; with a margin of 0.3 rad for the parallax, four."""
    six = _sweep_layout(6, math.radians(80.0))
    half_step = math.pi / 6
    for margin, reached in ((0.0, 2), (0.3, 4)):
        overlap = overlapping_images(six, six, half_step, margin)
        assert overlap is not None
        assert [len(row) for row in overlap] == [reached] * 6


def test_a_fit_compares_the_images_its_configured_margin_reaches(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``TwoViewConfig.overlap_margin_rad`` is the margin a fit guided by a rotation
    asks for; ``overlap_only=False`` asks for none (every image with every image)."""
    asked: list[float] = []
    real = twoview.overlapping_images

    def spy(a: SweepFeatures, b: SweepFeatures, rotation: float, margin: float):  # type: ignore[no-untyped-def]
        asked.append(margin)
        return real(a, b, rotation, margin)

    monkeypatch.setattr(twoview, "overlapping_images", spy)
    six = _sweep_layout(6, math.radians(80.0))
    fit_two_view(six, six, TwoViewConfig(overlap_margin_rad=0.123), guess_rad=0.0)
    assert asked and set(asked) == {0.123}
    asked.clear()
    fit_two_view(six, six, TwoViewConfig(overlap_only=False), guess_rad=0.0)
    assert asked == []


def test_matching_skips_images_that_cannot_overlap() -> None:
    # Two images with identical descriptors, looking opposite ways: matched in full,
    # the pair passes; with the layout, image 0 of one never meets image 1 of the other.
    rng = np.random.default_rng(3)
    desc = rng.integers(0, 256, (2, 32), dtype=np.uint8)
    two = SweepFeatures(
        np.zeros((2, 3)),
        desc,
        PIXEL_RAD,
        np.array([0, 1], np.uint8),
        np.array([0.0, math.pi]),
        math.radians(80.0),
    )
    other = replace(two, descriptors=desc[::-1].copy())
    ia, ib = _matches(two, other, 0.8)
    assert sorted(zip(ia.tolist(), ib.tolist(), strict=True)) == [(0, 1), (1, 0)]
    overlap = overlapping_images(two, other, 0.0, 0.3)
    ia, ib = _matches(two, other, 0.8, overlap)
    assert len(ia) == 0 and len(ib) == 0


def test_a_known_junction_keeps_40_bytes_a_keypoint_and_the_image_of_each() -> None:
    """The keypoints lie image by image, so a count per image names the image of each
    keypoint: 32 bytes of descriptor and 8 of position a keypoint, nothing more."""
    images = np.stack([_textured(20 + j, 400) for j in range(6)])
    images[3] = 128.0  # an image without a keypoint
    stored = stored_features(ImageSet(images, fov_rad=math.radians(80.0)))
    assert stored.per_image[3] == 0 and stored.per_image.sum() == len(stored) > 500
    assert stored.nbytes == 40 * len(stored) + stored.per_image.nbytes
    expected = np.concatenate([np.full(c, j, np.uint8) for j, c in enumerate(stored.per_image)])
    assert np.array_equal(stored.image, expected) and stored.image.dtype == np.uint8
    features = stored.features()
    assert features.image is not None and np.array_equal(features.image, expected)
    # Each keypoint's bearing looks out of its own image (60 degrees apart).
    assert features.image_azimuth_rad is not None
    azimuth = np.arctan2(features.bearings[:, 1], features.bearings[:, 0])
    looks = features.image_azimuth_rad[expected]
    off_axis = np.abs(np.remainder(azimuth - looks + math.pi, 2 * math.pi) - math.pi)
    assert off_axis.max() <= math.radians(40.0)
