"""Procedural textures of aged buried pipes, one seeded look per pipe and per junction.

The localizer tells junctions apart by normalized cross-correlation of camera images,
so no two pipes or chambers may share a texture: every one is drawn from a seeded
family of old concrete, vitrified clay and cast-iron looks (mottling, joints, stains,
drip streaks, encrustation, scratches, floor sediment) whose details differ, not their
colour code. Every size is given in metres and turned into pixels with the surface's
real extent, so a texture looks the same at any resolution.

Texture coordinates of :func:`pipe_texture`: columns (u) run along the pipe axis over
``length_m``; rows (v) run around the circumference, row 0 and the last row are the
floor and the middle row is the crown. The image wraps seamlessly in v. Because the
floor is at both ends and the crown in the middle, a renderer that flips v still puts
the sediment on the floor.

Texture coordinates of :func:`node_texture` (an equirectangular map of a spherical
chamber): columns are the longitude and wrap seamlessly; row 0 is the bottom pole
(the floor, with the sediment pool) and the last row the top pole.
"""

from __future__ import annotations

import math

import numpy as np

from pipemap.errors import SimError
from pipemap.sim.texture_layers import (
    PALETTES,
    apply_deposits,
    apply_joints,
    apply_scratches,
    apply_sediment,
    apply_stains,
    apply_streaks,
    finish,
    material_layers,
    smooth_towards_poles,
)
from pipemap.sim.texture_noise import Surface

__all__ = ["MATERIALS", "node_texture", "pipe_texture"]

#: Material families, by the name :func:`pipe_texture` and :func:`node_texture` accept.
MATERIALS = ("concrete", "clay", "cast_iron")
MIN_SIZE_PX = 16
MAX_SIZE_PX = 8192


def pipe_texture(
    rng: np.random.Generator,
    width_px: int = 1024,
    height_px: int = 512,
    length_m: float = 1.0,
    circumference_m: float = 0.2 * math.pi,
    material: str | None = None,
) -> np.ndarray:
    """Draw the inside surface of one aged pipe as an RGB image.

    Columns run along the pipe axis over ``length_m``; rows run around the
    ``circumference_m`` from the floor (row 0) over the crown (middle row) back to
    the floor (last row), and wrap seamlessly. ``material`` is one of
    :data:`MATERIALS`, or ``None`` to draw one from ``rng``.

    Returns a ``(height_px, width_px, 3)`` uint8 array. Raises
    :class:`~pipemap.errors.SimError` on a size below 16 or above 8192 pixels, a
    non-positive length or an unknown material.
    """
    _check_rng(rng)
    _check_size("width_px", width_px)
    _check_size("height_px", height_px)
    _check_length("length_m", length_m)
    _check_length("circumference_m", circumference_m)
    _check_material(material)
    name = material if material is not None else MATERIALS[int(rng.integers(len(MATERIALS)))]
    surf = Surface(int(height_px), int(width_px), float(circumference_m), float(length_m))
    pal = PALETTES[name]

    v = (np.arange(surf.height_px, dtype=np.float32) + 0.5) / surf.height_px
    floor_dist_m = (np.minimum(v, 1.0 - v) * surf.rows_m)[:, None]
    # Deposits and encrustation gather on the lower walls more than at the crown.
    deposit_bias = (0.7 + 0.3 * np.cos(2.0 * np.pi * v))[:, None]

    img, mottle = material_layers(rng, surf, pal)
    apply_stains(rng, surf, pal, img)
    half_m = 0.5 * surf.rows_m
    n_streaks = int(rng.poisson(rng.uniform(4.0, 14.0) * surf.cols_m * (surf.rows_m / 0.63)))
    start_m = half_m + rng.uniform(-0.12, 0.12, n_streaks) * surf.rows_m
    # A drip runs from the crown down one wall, towards the nearer floor row.
    direction = np.where(rng.random(n_streaks) < 0.5, -1.0, 1.0)
    length_m_ = rng.uniform(0.2, 0.85, n_streaks) * half_m
    apply_streaks(rng, surf, pal, img, start_m, direction, length_m_)
    apply_deposits(rng, surf, pal, img, deposit_bias)
    apply_joints(rng, surf, pal, img, mottle)
    apply_scratches(rng, surf, img)
    apply_sediment(rng, surf, pal, img, floor_dist_m, rng.uniform(0.05, 0.13) * surf.rows_m)
    return finish(rng, pal, img)


def node_texture(
    rng: np.random.Generator,
    width_px: int = 1024,
    height_px: int = 1024,
    radius_m: float = 0.2,
    material: str | None = None,
) -> np.ndarray:
    """Draw the inside of one spherical junction chamber as an equirectangular RGB image.

    Columns are the longitude (seamless wrap), rows the latitude from the bottom
    pole (row 0, the floor with a sediment pool) to the top pole (last row).
    ``radius_m`` sets the real size of the features; ``material`` is one of
    :data:`MATERIALS`, or ``None`` to draw one from ``rng``. There are no joints.

    Returns a ``(height_px, width_px, 3)`` uint8 array. Raises
    :class:`~pipemap.errors.SimError` on a size below 16 or above 8192 pixels, a
    non-positive radius or an unknown material.
    """
    _check_rng(rng)
    _check_size("width_px", width_px)
    _check_size("height_px", height_px)
    _check_length("radius_m", radius_m)
    _check_material(material)
    name = material if material is not None else MATERIALS[int(rng.integers(len(MATERIALS)))]
    surf = Surface(int(height_px), int(width_px), math.pi * radius_m, 2.0 * math.pi * radius_m)
    pal = PALETTES[name]

    v = (np.arange(surf.height_px, dtype=np.float32) + 0.5) / surf.height_px
    floor_dist_m = (v * surf.rows_m)[:, None]
    deposit_bias = (0.55 + 0.45 * (1.0 - v))[:, None]

    img, _ = material_layers(rng, surf, pal)
    apply_stains(rng, surf, pal, img)
    n_streaks = int(rng.poisson(rng.uniform(10.0, 30.0) * radius_m / 0.2))
    start_m = rng.uniform(0.55, 0.92, n_streaks) * surf.rows_m
    length_m_ = rng.uniform(0.15, 0.5, n_streaks) * surf.rows_m
    apply_streaks(rng, surf, pal, img, start_m, -np.ones(n_streaks), length_m_)
    apply_deposits(rng, surf, pal, img, deposit_bias)
    apply_scratches(rng, surf, img)
    apply_sediment(rng, surf, pal, img, floor_dist_m, rng.uniform(0.12, 0.25) * surf.rows_m)
    smooth_towards_poles(img)
    return finish(rng, pal, img)


# --- argument checks ---------------------------------------------------------------


def _check_rng(rng: object) -> None:
    if not isinstance(rng, np.random.Generator):
        raise SimError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")


def _check_size(name: str, value: object) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise SimError(f"{name} must be an integer, got {value!r}")
    if not MIN_SIZE_PX <= int(value) <= MAX_SIZE_PX:
        raise SimError(f"{name} must be in {MIN_SIZE_PX}..{MAX_SIZE_PX}, got {value}")


def _check_length(name: str, value: object) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise SimError(f"{name} must be a number, got {value!r}")
    if not (math.isfinite(float(value)) and float(value) > 0.0):
        raise SimError(f"{name} must be finite and positive, got {value}")


def _check_material(material: object) -> None:
    if material is not None and material not in MATERIALS:
        raise SimError(f"unknown material {material!r}; expected one of {MATERIALS}")
