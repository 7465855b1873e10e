"""Illumination normalisation: images of a dark pipe lit by the robot's own lamp.

A buried pipe has no light but the lamp the robot carries at its camera. Its light
falls with the square of the distance and with the angle of incidence, so every
view shows the same bright near wall and the same dark hole down the pipe, whatever
the junction. That shared vignette dominates a whole-image correlation: measured on
the paper's network (``benchmarks/bench_lamp.py``, docs/lighting.md), different
junctions scored up to 0.85 under a full-strength lamp, far above the paper's
threshold 0.36.

The lamp's light multiplies the wall's reflectance, and it varies slowly across
the image where the wall's stains, joints and openings vary fast. Dividing each
image by a wide Gaussian blur of itself (a flat-field correction by the image's own
estimate of its illumination, as retinex-style methods do) leaves the reflectance:
the near wall and the far wall then show their texture at one contrast. Where the
blur is darker than ``floor`` grey levels (beyond the lamp's reach) there is
nothing to recover, and the floor keeps the sensor's noise from being amplified.

Pure numpy and OpenCV on images; the localizer applies it to every sweep it sees
when :attr:`localizer.LocalizerConfig.lamp` says the camera is lamp-lit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from pipemap.errors import LocalizerError
from pipemap.localizer.imageset import ImageSet

__all__ = ["IlluminationConfig", "normalised"]


@dataclass(frozen=True)
class IlluminationConfig:
    """Settings of :func:`normalised`."""

    #: Sigma of the illumination estimate, as a fraction of the image width.
    sigma_fraction: float = 0.0625
    #: Grey levels added to the estimate before dividing: darker regions stay dark.
    floor: float = 2.0
    #: The grey level a wall of average reflectance gets.
    level: float = 100.0

    def __post_init__(self) -> None:
        if not 0.0 < self.sigma_fraction <= 1.0:
            raise LocalizerError(f"sigma_fraction must be in (0, 1], got {self.sigma_fraction}")
        if not self.floor > 0.0:
            raise LocalizerError(f"floor must be > 0 grey levels, got {self.floor}")
        if not 0.0 < self.level <= 255.0:
            raise LocalizerError(f"level must be in (0, 255], got {self.level}")


def _blurred(image: np.ndarray, sigma_px: float) -> np.ndarray:
    """A Gaussian blur of ``sigma_px``, computed on an image shrunk by a whole factor
    of up to sigma/4 (a blur this wide is smooth) and enlarged again.

    The factor is the largest one up to sigma/4 that divides both sides, so the
    shrinking averages whole blocks of pixels: OpenCV's ``INTER_AREA`` then takes its
    fast path (0.06 ms for a 400 px image by 5, against 0.32 ms by 400/66 = 6.06, the
    factor before stop 35), and the small image's pixels lie on the large one's grid.
    Sides with no common divisor of at least half of sigma/4 (401 by 397 px, say) are
    first extended by reflection at the bottom and right to multiples of sigma/4:
    blurred at full size they would cost a hundred times as much.
    """
    h, w = image.shape
    most = max(1, min(int(sigma_px // 4), h // 4, w // 4))
    common = math.gcd(h, w)
    factor = max(f for f in range(1, most + 1) if common % f == 0)
    if 2 * factor < most:
        factor = most
        image = cv2.copyMakeBorder(image, 0, -h % factor, 0, -w % factor, cv2.BORDER_REFLECT)
    rows, cols = image.shape
    small = cv2.resize(image, (cols // factor, rows // factor), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), sigma_px / factor, borderType=cv2.BORDER_REFLECT)
    out: np.ndarray = cv2.resize(small, (cols, rows), interpolation=cv2.INTER_LINEAR)[:h, :w]
    return out


def normalised(image_set: ImageSet, config: IlluminationConfig | None = None) -> ImageSet:
    """The set with each image divided by its own illumination estimate.

    Every pixel becomes ``level * image / (blur + floor)``, clipped to 0..255: a
    wall lit twice as brightly keeps its value, and an evenly lit image changes
    only by its slow shading. The whole image is filtered (the kept top part's
    lower edge sees its true neighbours); the set's geometry is kept.
    """
    config = config if config is not None else IlluminationConfig()
    images = np.asarray(image_set.images, dtype=np.float32)
    sigma_px = config.sigma_fraction * image_set.width
    out = np.empty_like(images)
    for i, image in enumerate(images):
        light = _blurred(image, sigma_px)
        light += config.floor
        # level * (image + floor) / (light + floor), clipped, in place: the very
        # float32 operations in the same order, a third less time than with temporaries.
        lit = out[i]
        np.add(image, config.floor, out=lit)
        lit *= config.level
        lit /= light
        np.clip(lit, 0.0, 255.0, out=lit)
    return replace(image_set, images=out)
