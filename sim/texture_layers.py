"""The looks of aged pipe surfaces that :mod:`sim.textures` layers onto each other: the
material families' palettes, and the features drawn from the seed (mottling, stains,
drip streaks, encrustation, joints, scratches, floor sediment)."""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from pipemap.sim.texture_noise import (
    Rgb,
    Surface,
    blend,
    jitter,
    mask_above_quantile,
    noise,
    smoothstep,
)

__all__ = [
    "PALETTES",
    "Palette",
    "apply_deposits",
    "apply_joints",
    "apply_scratches",
    "apply_sediment",
    "apply_stains",
    "apply_streaks",
    "finish",
    "material_layers",
    "smooth_towards_poles",
]


@dataclass(frozen=True)
class Palette:
    """Colours and strengths of one material family (RGB in 0..255)."""

    base_rgb: Rgb
    alt_rgb: Rgb
    stain_rgb: Rgb
    deposit_rgb: Rgb
    sediment_rgb: Rgb
    mortar_rgb: Rgb
    mottle_amp: float
    grain_amp: float
    stain_strength: float
    deposit_strength: float
    speckle_strength: float
    mean_gray_range: tuple[float, float]


PALETTES = {
    "concrete": Palette(
        base_rgb=(138, 135, 128),
        alt_rgb=(118, 112, 100),
        stain_rgb=(62, 52, 40),
        deposit_rgb=(205, 200, 186),
        sediment_rgb=(112, 96, 74),
        mortar_rgb=(178, 174, 164),
        mottle_amp=0.13,
        grain_amp=0.08,
        stain_strength=0.55,
        deposit_strength=0.55,
        speckle_strength=0.35,
        mean_gray_range=(108.0, 145.0),
    ),
    "clay": Palette(
        base_rgb=(172, 100, 58),
        alt_rgb=(140, 78, 48),
        stain_rgb=(58, 38, 26),
        deposit_rgb=(196, 184, 160),
        sediment_rgb=(104, 92, 76),
        mortar_rgb=(170, 162, 146),
        mottle_amp=0.10,
        grain_amp=0.05,
        stain_strength=0.45,
        deposit_strength=0.45,
        speckle_strength=0.15,
        mean_gray_range=(96.0, 132.0),
    ),
    "cast_iron": Palette(
        base_rgb=(92, 86, 82),
        alt_rgb=(150, 84, 44),
        stain_rgb=(112, 52, 24),
        deposit_rgb=(176, 100, 52),
        sediment_rgb=(92, 80, 66),
        mortar_rgb=(150, 142, 128),
        mottle_amp=0.16,
        grain_amp=0.09,
        stain_strength=0.6,
        deposit_strength=0.7,
        speckle_strength=0.2,
        mean_gray_range=(90.0, 116.0),
    ),
}


def material_layers(
    rng: np.random.Generator, surf: Surface, pal: Palette
) -> tuple[np.ndarray, np.ndarray]:
    """Base colour with mottling, a second tone, fine grain and aggregate speckle."""
    mottle = noise(rng, surf, 0.6, 0.02, slope=1.6)
    tone = noise(rng, surf, 0.35, 0.015, slope=1.3)
    grain = noise(rng, surf, 0.006, 0.0008, slope=0.6)
    speckle = noise(rng, surf, 0.01, 0.002, slope=0.8)
    base = jitter(rng, pal.base_rgb, 0.08)
    alt = jitter(rng, pal.alt_rgb, 0.1)
    tone_share = float(rng.uniform(0.25, 0.6))
    img = np.empty((surf.height_px, surf.width_px, 3), dtype=np.float32)
    img[...] = base
    blend(img, alt, tone_share * smoothstep(-0.6, 1.4, tone))
    shade = 1.0 + float(rng.uniform(0.7, 1.3)) * pal.mottle_amp * mottle
    shade += pal.grain_amp * grain
    img *= shade[..., None]
    # Exposed aggregate (concrete), glaze pits (clay), graphitised pits (iron).
    spots = mask_above_quantile(speckle, float(rng.uniform(0.86, 0.95)), 0.7)
    sign = np.where(noise(rng, surf, 0.02, 0.004, slope=0.5) > 0.0, 1.25, 0.7)
    img *= (1.0 + pal.speckle_strength * spots * (sign - 1.0))[..., None]
    return img, mottle


def apply_stains(rng: np.random.Generator, surf: Surface, pal: Palette, img: np.ndarray) -> None:
    """Dark or rust-coloured blotches of varied size."""
    field = noise(rng, surf, 0.25, 0.006, slope=1.3)
    mask = mask_above_quantile(field, float(rng.uniform(0.72, 0.9)), 0.9)
    colour = jitter(rng, pal.stain_rgb, 0.15)
    blend(img, colour, pal.stain_strength * float(rng.uniform(0.6, 1.0)) * mask)


def apply_streaks(
    rng: np.random.Generator,
    surf: Surface,
    pal: Palette,
    img: np.ndarray,
    start_m: np.ndarray,
    direction: np.ndarray,
    length_m: np.ndarray,
) -> None:
    """Drip streaks running along the rows (down the wall), mostly dark, some light.

    Each streak starts at ``start_m`` (metres along the rows), runs ``length_m``
    towards decreasing (``direction`` -1) or increasing (+1) rows and fades out.
    """
    n = len(start_m)
    dark = np.zeros((surf.height_px, surf.width_px), dtype=np.float32)
    light = np.zeros_like(dark)
    u_m = rng.uniform(0.0, surf.cols_m, n)
    width_m = rng.uniform(0.0012, 0.006, n)
    strength = rng.uniform(0.25, 0.7, n)
    is_light = rng.random(n) < 0.25
    wiggle_m = rng.uniform(0.0, 0.004, n)
    wiggle_cycles = rng.uniform(0.5, 3.0, n)
    wiggle_phase = rng.uniform(0.0, 2.0 * np.pi, n)
    fade_power = rng.uniform(0.7, 2.5, n)
    for i in range(n):
        rows_n = max(2, int(length_m[i] / surf.row_px_m))
        r0 = int(start_m[i] / surf.row_px_m)
        rows = (r0 + direction[i] * np.arange(rows_n)).astype(np.int64) % surf.height_px
        t = np.linspace(0.0, 1.0, rows_n, dtype=np.float32)
        along = (1.0 - t) ** fade_power[i] * np.minimum(1.0, t * 12.0 + 0.2)
        center_m = u_m[i] + wiggle_m[i] * np.sin(2 * np.pi * wiggle_cycles[i] * t + wiggle_phase[i])
        # The drip spreads a little as it runs down.
        sigma_m = width_m[i] * (0.7 + 0.8 * t)
        half_cols = int(np.ceil((3.0 * width_m[i] * 1.5 + wiggle_m[i]) / surf.col_px_m)) + 1
        c0 = int(u_m[i] / surf.col_px_m)
        cols = np.arange(c0 - half_cols, c0 + half_cols + 1)
        col_m = (cols + 0.5) * surf.col_px_m
        across = np.exp(-0.5 * ((col_m[None, :] - center_m[:, None]) / sigma_m[:, None]) ** 2)
        target = light if is_light[i] else dark
        patch = (strength[i] * along[:, None] * across).astype(np.float32)
        ix = np.ix_(rows, cols % surf.width_px)
        target[ix] = np.maximum(target[ix], patch)
    blend(img, jitter(rng, pal.stain_rgb, 0.1), dark)
    blend(img, jitter(rng, pal.deposit_rgb, 0.05), 0.7 * light)


def apply_deposits(
    rng: np.random.Generator, surf: Surface, pal: Palette, img: np.ndarray, bias: np.ndarray
) -> None:
    """Light, rough, irregular encrustation (rust tubercles on cast iron), lit from above."""
    field = noise(rng, surf, 0.15, 0.005, slope=1.2) * bias
    mask = mask_above_quantile(field, float(rng.uniform(0.8, 0.93)), 0.6)
    rough = noise(rng, surf, 0.006, 0.001, slope=0.7)
    colour = jitter(rng, pal.deposit_rgb, 0.08)
    alpha = pal.deposit_strength * mask * np.clip(0.65 + 0.35 * rough, 0.0, 1.0)
    blend(img, colour, alpha)
    # Emboss: brightness follows the slope of the crust so it reads as raised.
    relief = mask * (1.5 + rough)
    slope = np.roll(relief, 1, axis=0) - np.roll(relief, -1, axis=0)
    slope += np.roll(relief, 1, axis=1) - np.roll(relief, -1, axis=1)
    img *= (1.0 + 0.12 * slope)[..., None]


def apply_joints(
    rng: np.random.Generator, surf: Surface, pal: Palette, img: np.ndarray, mottle: np.ndarray
) -> None:
    """Dark rings around the full circumference at a regular spacing, some with mortar."""
    spacing_m = float(rng.uniform(0.3, 1.0))
    phase_m = float(rng.uniform(0.0, spacing_m))
    gap_m = max(float(rng.uniform(0.003, 0.01)), 1.5 * surf.col_px_m)
    depth = float(rng.uniform(0.5, 0.72))
    has_mortar = bool(rng.random() < 0.5)
    mortar_m = float(rng.uniform(0.012, 0.03))
    n_joints = int(surf.cols_m / spacing_m) + 3
    wobble_m = rng.uniform(0.0, 0.004, n_joints).astype(np.float32)
    wobble_phase = rng.uniform(0.0, 2.0 * np.pi, n_joints).astype(np.float32)
    ragged = noise(rng, surf, 0.03, 0.003, slope=1.0)

    u = ((np.arange(surf.width_px, dtype=np.float32) + 0.5) * surf.col_px_m)[None, :]
    v = ((np.arange(surf.height_px, dtype=np.float32) + 0.5) / surf.height_px)[:, None]
    k = np.clip(np.floor((u - phase_m) / spacing_m + 0.5).astype(np.int64) + 1, 0, n_joints - 1)
    center = phase_m + (k - 1) * spacing_m
    offset = wobble_m[k] * np.sin(2.0 * np.pi * v + wobble_phase[k])
    dist = np.abs(u - center - offset)
    if has_mortar:
        edge = 0.5 * mortar_m * (1.0 + 0.45 * ragged)
        blend(img, jitter(rng, pal.mortar_rgb, 0.08), 0.7 * smoothstep(-0.001, 0.001, edge - dist))
    dark = depth * np.exp(-0.5 * (dist / (0.5 * gap_m)) ** 2) * (0.85 + 0.15 * np.tanh(mottle))
    img *= (1.0 - dark)[..., None]


def apply_scratches(rng: np.random.Generator, surf: Surface, img: np.ndarray) -> None:
    """Thin bright or dark lines, slightly bent, at random angles, wrapping at the borders."""
    area_m2 = surf.rows_m * surf.cols_m
    n = int(rng.poisson(rng.uniform(20.0, 90.0) * area_m2))
    canvases = np.zeros((2, surf.height_px, surf.width_px), dtype=np.uint8)
    scale = np.array([1.0 / surf.col_px_m, 1.0 / surf.row_px_m])
    shift = 4
    for _ in range(n):
        centre_m = rng.uniform((0.0, 0.0), (surf.cols_m, surf.rows_m))
        angle = rng.uniform(0.0, np.pi)
        length = rng.uniform(0.015, 0.15)
        bend = rng.uniform(-0.1, 0.1) * length
        t = np.linspace(-0.5, 0.5, 6)[:, None]
        along = np.array([np.cos(angle), np.sin(angle)])
        normal = np.array([-along[1], along[0]])
        pts_m = centre_m + t * length * along + (1.0 - 4.0 * t**2) * bend * normal
        pts_px = pts_m * scale
        thickness = 1 if rng.random() < 0.75 else 2
        value = int(rng.integers(70, 200))
        which = int(rng.random() < 0.55)
        lo, hi = pts_px.min(axis=0), pts_px.max(axis=0)
        for dx in (-surf.width_px, 0, surf.width_px):
            for dy in (-surf.height_px, 0, surf.height_px):
                if hi[0] + dx < -2 or lo[0] + dx > surf.width_px + 2:
                    continue
                if hi[1] + dy < -2 or lo[1] + dy > surf.height_px + 2:
                    continue
                fixed = np.round((pts_px + (dx, dy)) * (1 << shift)).astype(np.int32)
                cv2.polylines(canvases[which], [fixed], False, value, thickness, cv2.LINE_AA, shift)
    bright = canvases[1].astype(np.float32) * (0.55 / 255.0)
    dark = canvases[0].astype(np.float32) * (0.5 / 255.0)
    img *= (1.0 - dark)[..., None]
    img += (bright[..., None] * (235.0 - img)).clip(min=0.0)


def apply_sediment(
    rng: np.random.Generator,
    surf: Surface,
    pal: Palette,
    img: np.ndarray,
    floor_dist_m: np.ndarray,
    mean_reach_m: float,
) -> None:
    """Sediment over the floor, reaching a ragged, varying distance up the walls.

    ``floor_dist_m`` is each row's distance from the floor along the surface (a
    column vector), ``mean_reach_m`` how far the sediment reaches on average.
    """
    swell = noise(rng, surf, 0.4, 0.05, slope=1.8)
    ragged = noise(rng, surf, 0.03, 0.002, slope=1.1)
    reach = mean_reach_m * (1.0 + 0.35 * swell) + float(rng.uniform(0.002, 0.007)) * ragged
    inside = reach - floor_dist_m
    mask = smoothstep(-0.0015, 0.0015, inside)
    colour = jitter(rng, pal.sediment_rgb, 0.12)
    texture = noise(rng, surf, 0.01, 0.0015, slope=0.8)
    pebbles = mask_above_quantile(noise(rng, surf, 0.012, 0.003, slope=0.6), 0.93, 0.5)
    sed = np.empty_like(img)
    sed[...] = colour
    sed *= (1.0 + 0.14 * texture + 0.4 * pebbles)[..., None]
    # A damp rim just inside the edge, where the water line sat.
    rim = np.exp(-0.5 * ((inside - 0.004) / 0.003) ** 2)
    sed *= (1.0 - float(rng.uniform(0.1, 0.3)) * rim)[..., None]
    blend(img, np.zeros(3, dtype=np.float32), mask)
    img += sed * mask[..., None]


def smooth_towards_poles(img: np.ndarray) -> None:
    """Blur each row along the longitude by 1/cos(latitude) pixels, in place.

    Near the poles a row shrinks to a point on the sphere; without this the
    texture would pinch into a star of streaks there.
    """
    h, w = img.shape[:2]
    lat = np.pi * ((np.arange(h) + 0.5) / h - 0.5)
    half = np.minimum(np.round(0.5 / np.maximum(np.cos(lat), 1e-6) - 0.5), (w - 1) // 2)
    rows = np.nonzero(half >= 1)[0]
    if rows.size == 0:
        return
    pad = int(half.max()) + 1
    band = img[rows].astype(np.float64)
    padded = np.concatenate([band[:, -pad:], band, band[:, :pad]], axis=1)
    csum = np.cumsum(padded, axis=1)
    csum = np.concatenate([np.zeros_like(csum[:, :1]), csum], axis=1)
    k = half[rows].astype(np.int64)[:, None]
    j = np.arange(w)[None, :] + pad
    hi = np.broadcast_to(j + k + 1, (rows.size, w))[..., None]
    lo = np.broadcast_to(j - k, (rows.size, w))[..., None]
    hi3 = np.broadcast_to(hi, (rows.size, w, 3))
    lo3 = np.broadcast_to(lo, (rows.size, w, 3))
    total = np.take_along_axis(csum, hi3, axis=1) - np.take_along_axis(csum, lo3, axis=1)
    img[rows] = (total / (2 * k + 1)[..., None]).astype(np.float32)


def finish(rng: np.random.Generator, pal: Palette, img: np.ndarray) -> np.ndarray:
    """Bring the mean brightness into the material's range and quantise to uint8."""
    lo, hi = pal.mean_gray_range
    gray = float(img.mean())
    target = float(np.clip(gray, lo, hi))
    # A little extra spread so pipes of one material are not all equally bright.
    target *= float(rng.uniform(0.97, 1.03))
    img *= target / max(gray, 1e-6)
    return np.clip(img + 0.5, 0.0, 255.0).astype(np.uint8)
