"""The building blocks of :mod:`sim.textures`: a rectangle of surface with its real
extent, seeded multi-scale noise that wraps seamlessly, soft masks and colour blending.
Every size is in metres, turned into pixels with the surface's extent."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = [
    "Rgb",
    "Surface",
    "blend",
    "jitter",
    "mask_above_quantile",
    "noise",
    "resample_wrapped",
    "smoothstep",
]

Rgb = tuple[float, float, float]


@dataclass(frozen=True)
class Surface:
    """A rectangle of texture and the real extent its rows and columns cover."""

    height_px: int
    width_px: int
    rows_m: float
    cols_m: float

    @property
    def row_px_m(self) -> float:
        """Metres of surface one pixel row covers."""
        return self.rows_m / self.height_px

    @property
    def col_px_m(self) -> float:
        """Metres of surface one pixel column covers."""
        return self.cols_m / self.width_px


def noise(
    rng: np.random.Generator,
    surf: Surface,
    coarsest_m: float,
    finest_m: float,
    slope: float = 1.5,
) -> np.ndarray:
    """Multi-scale noise by spectral synthesis: zero mean, unit std, periodic both ways.

    Blobs range from about ``coarsest_m`` down to ``finest_m``; ``slope`` is the
    fall of the amplitude spectrum (1 gives equal energy per octave). Fields
    without fine detail are made on a coarser grid and resampled with wrap-around.
    """
    finest_m = max(finest_m, 1.2 * max(surf.row_px_m, surf.col_px_m))
    fy = int(np.clip(finest_m / (3.0 * surf.row_px_m), 1, 8))
    fx = int(np.clip(finest_m / (3.0 * surf.col_px_m), 1, 8))
    h = max(8, -(-surf.height_px // fy))
    w = max(8, -(-surf.width_px // fx))
    ky = np.fft.fftfreq(h, d=surf.rows_m / h).astype(np.float32)
    kx = np.fft.rfftfreq(w, d=surf.cols_m / w).astype(np.float32)
    k2 = ky[:, None] ** 2 + kx[None, :] ** 2
    k_low = 1.0 / coarsest_m
    k_high = 1.0 / (2.0 * finest_m)
    amp = (k2 + k_low**2) ** (-0.5 * slope) * np.exp(-0.5 * k2 / k_high**2)
    amp[0, 0] = 0.0
    shape = (h, w // 2 + 1)
    spec = rng.standard_normal(shape, dtype=np.float32) + 1j * rng.standard_normal(
        shape, dtype=np.float32
    )
    field = np.fft.irfft2(spec * amp, s=(h, w)).astype(np.float32)
    field -= field.mean()
    field /= max(float(field.std()), 1e-12)
    if (h, w) != (surf.height_px, surf.width_px):
        field = resample_wrapped(field, surf.height_px, surf.width_px)
    return field


def resample_wrapped(field: np.ndarray, height_px: int, width_px: int) -> np.ndarray:
    """Resize a periodic field so that it stays periodic (cubic, wrap-around border)."""
    sy = field.shape[0] / height_px
    sx = field.shape[1] / width_px
    m = np.array([[sx, 0.0, 0.5 * sx - 0.5], [0.0, sy, 0.5 * sy - 0.5]], dtype=np.float32)
    out = cv2.warpAffine(
        field,
        m,
        (width_px, height_px),
        flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_WRAP,
    )
    return np.asarray(out, dtype=np.float32)


def smoothstep(edge0: float, edge1: float, x: np.ndarray) -> np.ndarray:
    """0 below ``edge0``, 1 above ``edge1``, a smooth cubic between."""
    t = np.clip((x - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def mask_above_quantile(field: np.ndarray, quantile: float, softness: float) -> np.ndarray:
    """0..1 mask of where ``field`` exceeds its ``quantile``, with soft edges."""
    # A sparse sample keeps the quantile cheap; its exact value does not matter.
    thr = float(np.quantile(field[::7, ::5], quantile))
    return smoothstep(thr, thr + softness, field)


def jitter(rng: np.random.Generator, rgb: Rgb, spread: float) -> np.ndarray:
    """A colour shifted in brightness and slightly in tint, so each pipe is its own."""
    gain = rng.uniform(1.0 - spread, 1.0 + spread)
    tint = rng.uniform(1.0 - 0.35 * spread, 1.0 + 0.35 * spread, 3)
    colour: np.ndarray = (
        np.asarray(rgb, dtype=np.float32) * np.float32(gain) * tint.astype(np.float32)
    )
    return colour


def blend(img: np.ndarray, rgb: np.ndarray, alpha: np.ndarray) -> None:
    """In place: ``img = img * (1 - alpha) + rgb * alpha`` with a per-pixel alpha."""
    a = np.clip(alpha, 0.0, 1.0)[..., None]
    img *= 1.0 - a
    img += a * rgb
