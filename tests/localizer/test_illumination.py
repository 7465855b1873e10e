"""Illumination normalisation: a lamp's shared vignette must not make junctions alike."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer import (
    IlluminationConfig,
    ImageSet,
    Localizer,
    LocalizerConfig,
    normalised,
    reference_match,
)
from pipemap.localizer import illumination as illumination_module
from pipemap.localizer import verify as verify_module
from tests.localizer.synthetic import ROWS, WIDTH, panorama, sweep


def _vignette(rows: int = ROWS, width: int = WIDTH) -> np.ndarray:
    """A lamp at the camera: a bright wall in the middle, dark towards every edge."""
    y, x = np.mgrid[0:rows, 0:width].astype(np.float32)
    r2 = ((x - width / 2) / (width / 2)) ** 2 + ((y - rows) / rows) ** 2
    return (1.6 / (1.0 + 3.0 * r2)).astype(np.float32)


def _lit(image_set: ImageSet, light: np.ndarray) -> ImageSet:
    return replace(image_set, images=np.clip(image_set.images * light, 0.0, 255.0))


def test_different_junctions_under_one_lamp_look_alike_unless_normalised() -> None:
    light = _vignette()
    a = _lit(sweep(panorama(1)), light)
    b = _lit(sweep(panorama(2)), light)
    raw = reference_match(a, b).similarity
    flat = reference_match(normalised(a), normalised(b)).similarity
    assert raw > 0.45  # the vignette alone makes them alike (threshold 0.36)
    assert flat < 0.2


def test_normalisation_keeps_a_junction_recognisable_under_two_lamps() -> None:
    pano = panorama(4)
    a = _lit(sweep(pano), _vignette())
    b = _lit(sweep(pano, turn=37), 0.5 * _vignette())  # a dimmer lamp, turned
    match = reference_match(normalised(a), normalised(b))
    assert match.similarity > 0.8


def test_normalisation_keeps_the_geometry_and_range() -> None:
    s = _lit(sweep(panorama(5)), _vignette())
    out = normalised(s)
    assert out.images.shape == s.images.shape
    assert out.fov_rad == s.fov_rad and out.camera_angle_rad == s.camera_angle_rad
    assert float(out.images.min()) >= 0.0 and float(out.images.max()) <= 255.0
    # Darkness stays the neutral level, not amplified noise.
    dark = normalised(replace(s, images=np.zeros_like(s.images)))
    assert np.allclose(dark.images, IlluminationConfig().level)


@pytest.mark.parametrize(
    "kwargs", [{"sigma_fraction": 0.0}, {"sigma_fraction": 1.5}, {"floor": 0.0}, {"level": 300.0}]
)
def test_bad_settings_are_refused(kwargs: dict[str, float]) -> None:
    with pytest.raises(LocalizerError):
        IlluminationConfig(**kwargs)


def _paper_rules(**kwargs: object) -> LocalizerConfig:
    return LocalizerConfig(
        active_vision=False, two_view=False, verify=False, distinct_consecutive=False, **kwargs
    )


def test_the_localizer_normalises_only_lamp_lit_sweeps() -> None:
    light = _vignette()
    a = _lit(sweep(panorama(1)), light)
    b = _lit(sweep(panorama(2)), light)
    for lamp, known in ((False, True), (True, False)):
        localizer = Localizer(_paper_rules(lamp=lamp))
        localizer.localize(a)
        assert localizer.localize(b).known is known, lamp


def test_for_camera_fills_in_only_an_unset_lamp() -> None:
    assert LocalizerConfig().lamp is None
    assert LocalizerConfig().for_camera(True).lamp is True
    assert LocalizerConfig().for_camera(False).lamp is False
    assert LocalizerConfig(lamp=False).for_camera(True).lamp is False
    assert LocalizerConfig(lamp=True).for_camera(False).lamp is True


@pytest.mark.parametrize("lamp", [False, True])
def test_under_a_lamp_a_failed_fit_is_tried_again_at_any_rotation(
    lamp: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Under a lamp the NCC may turn a cross junction by a quarter: the fit at its
    rotation fails, and only a fit free of that guess finds the junction."""
    real = verify_module.fit_two_view
    guesses: list[float | None] = []

    def guided_fails(query, known, config=None, guess_rad=None, cache=None):  # type: ignore[no-untyped-def]
        guesses.append(guess_rad)
        return None if guess_rad is not None else real(query, known, config, None, cache)

    monkeypatch.setattr(verify_module, "fit_two_view", guided_fails)
    config = LocalizerConfig(
        active_vision=False, distinct_consecutive=False, verify_min_keypoints=10, lamp=lamp
    )
    a = sweep(panorama(7))
    localizer = Localizer(config)
    localizer.localize(a)
    decision = localizer.localize(sweep(panorama(7), turn=11), None)
    assert decision.known is lamp
    assert (None in guesses) is lamp


@pytest.mark.parametrize(
    ("shape", "factor"),
    [((400, 400), 5), ((200, 200), 2), ((400, 300), 4), ((96, 96), 1), ((401, 397), 6)],
)
def test_the_blur_shrinks_by_a_whole_factor(
    shape: tuple[int, int], factor: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The illumination estimate is blurred on an image shrunk by the largest whole
    factor up to sigma/4 that divides both sides: whole blocks of pixels averaged, so
    the small grid lies on the large one (a factor of 400/66 = 6.06 did not), and
    close to the blur at full size. Sides with no such divisor of at least half of
    sigma/4 (401 by 397 px) are extended to multiples of sigma/4 first, and the result
    is cut back to the image's own size."""
    sizes: list[tuple[int, int]] = []
    real_resize = illumination_module.cv2.resize

    def recording_resize(image: np.ndarray, size: tuple[int, int], **kwargs: object) -> np.ndarray:
        sizes.append(size)
        return real_resize(image, size, **kwargs)

    monkeypatch.setattr(illumination_module.cv2, "resize", recording_resize)
    h, w = shape
    sigma = IlluminationConfig().sigma_fraction * w
    y, x = np.mgrid[0:h, 0:w].astype(np.float32)
    image = (100 + 60 * np.sin(x / 17.0) * np.cos(y / 23.0) + 0.2 * x).astype(np.float32)
    blurred = illumination_module._blurred(image, sigma)
    padded_w, padded_h = w + -w % factor, h + -h % factor
    assert sizes[0] == (padded_w // factor, padded_h // factor)
    assert padded_w - w < factor and padded_h - h < factor
    assert blurred.shape == image.shape
    exact = illumination_module.cv2.GaussianBlur(
        image, (0, 0), sigma, borderType=illumination_module.cv2.BORDER_REFLECT
    )
    inner = (slice(h // 8, h - h // 8), slice(w // 8, w - w // 8))
    assert float(np.abs(blurred - exact)[inner].max()) < 1.0  # grey levels


def test_every_pixel_is_the_documented_quotient_bit_for_bit() -> None:
    """``level * (image + floor) / (blur + floor)``, clipped: computed in place, it must
    be the very float32 result of the formula as written (the map bytes of every
    lamp-lit log depend on it)."""
    config = IlluminationConfig(floor=3.0, level=90.0)
    s = _lit(sweep(panorama(6)), _vignette())
    out = normalised(s, config).images
    sigma = config.sigma_fraction * s.width
    for image, got in zip(np.asarray(s.images, dtype=np.float32), out, strict=True):
        light = illumination_module._blurred(image, sigma)
        want = np.clip(config.level * (image + config.floor) / (light + config.floor), 0.0, 255.0)
        assert want.dtype == got.dtype == np.float32
        assert np.array_equal(want, got)
