"""Synthetic image sets cut from a smooth random panorama: exact ground truth.

Image j of a sweep shows panorama columns ``[j * step + turn, j * step + turn + width)``
(cyclically), so a panorama of ``N * step`` columns spans 2*pi and the field of view of
an image is ``width / (N * step) * 2*pi``. Turning the sweep by ``turn`` columns moves
content from column x of the first sweep to column ``x - turn`` of the second.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from pipemap.localizer import ImageSet

ROWS = 192
STEP = 240
WIDTH = 320


def panorama(seed: int, count: int = 6, rows: int = ROWS, step: int = STEP) -> np.ndarray:
    """A smooth random texture of ``rows x count*step`` pixels, values in 0..255."""
    rng = np.random.default_rng(seed)
    cols = count * step
    noise = rng.normal(size=(rows, cols)).astype(np.float32)
    # Blur with wrap-around so the panorama closes on itself.
    wide = np.concatenate([noise[:, -32:], noise, noise[:, :32]], axis=1)
    smooth = cv2.GaussianBlur(wide, (0, 0), 3.0)[:, 32:-32]
    smooth = (smooth - smooth.mean()) / smooth.std()
    return np.clip(128.0 + 40.0 * smooth, 0.0, 255.0)


def sweep(pano: np.ndarray, count: int = 6, turn: int = 0, width: int = WIDTH) -> ImageSet:
    """The N images a camera turning in equal steps sees of ``pano``, turned by ``turn``."""
    cols = pano.shape[1]
    step = cols // count
    images = [pano[:, (np.arange(width) + j * step + turn) % cols] for j in range(count)]
    return ImageSet(np.stack(images), fov_rad=width / cols * 2.0 * math.pi)


def expected_rotation_rad(turn: int, cols: int) -> float:
    """Rotation of a sweep turned by ``turn`` columns relative to the unturned one."""
    return math.remainder(-turn * 2.0 * math.pi / cols, 2.0 * math.pi)
