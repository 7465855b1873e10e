"""Procedural pipe and chamber textures: seeded, varied, seamless, checked (small sizes)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from pipemap.errors import SimError
from pipemap.sim.textures import MATERIALS, node_texture, pipe_texture

# Small textures keep the module fast; every size is metric, so the look holds.
PIPE_PX = {"width_px": 128, "height_px": 64}
NODE_PX = {"width_px": 64, "height_px": 64}
KINDS: dict[str, tuple[Callable[..., np.ndarray], dict[str, int]]] = {
    "pipe": (pipe_texture, PIPE_PX),
    "node": (node_texture, NODE_PX),
}


def _texture(kind: str, seed: int, **kwargs: Any) -> np.ndarray:
    draw, size = KINDS[kind]
    return draw(np.random.default_rng(seed), **{**size, **kwargs})


def _gray(image: np.ndarray) -> np.ndarray:
    gray: np.ndarray = image.astype(np.float64).mean(axis=2)
    return gray


def _band_rgb(image: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Mean colour of the rows between fractions ``lo`` and ``hi`` of the height."""
    h = image.shape[0]
    rgb: np.ndarray = image[int(lo * h) : int(hi * h)].reshape(-1, 3).astype(np.float64).mean(0)
    return rgb


def _red_share(image: np.ndarray) -> float:
    rgb = image.reshape(-1, 3).astype(np.float64).mean(axis=0)
    return float(rgb[0] / rgb.sum())


def _ncc(a: np.ndarray, b: np.ndarray) -> float:
    a = a - a.mean()
    b = b - b.mean()
    return float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))


def _seam_to_step_ratio(fields: list[np.ndarray]) -> float:
    """Mean step across the wrap (last row to row 0) over the mean step between rows.

    Fine grain makes single steps noisy, so both means run over several textures.
    """
    seam = np.mean([np.abs(f[-1] - f[0]).mean() for f in fields])
    step = np.mean([np.abs(np.diff(f, axis=0)).mean() for f in fields])
    return float(seam / step)


@pytest.mark.parametrize("kind", ["pipe", "node"])
def test_same_seed_gives_bit_identical_textures(kind: str) -> None:
    one = _texture(kind, 7)
    two = _texture(kind, 7)
    assert np.array_equal(one, two)


@pytest.mark.parametrize("kind", ["pipe", "node"])
@pytest.mark.parametrize("material", MATERIALS)
def test_different_seeds_give_distinguishable_textures(kind: str, material: str) -> None:
    grays = [_gray(_texture(kind, seed, material=material)) for seed in range(4)]
    for i in range(len(grays)):
        for j in range(i + 1, len(grays)):
            assert np.abs(grays[i] - grays[j]).mean() > 8.0, (i, j)
            # The localizer matches by NCC: another pipe or chamber must not look alike.
            assert _ncc(grays[i], grays[j]) < 0.5, (i, j)


@pytest.mark.parametrize("kind", ["pipe", "node"])
@pytest.mark.parametrize(("width_px", "height_px"), [(16, 16), (48, 16), (16, 40), (96, 32)])
def test_texture_has_the_requested_shape_and_dtype(
    kind: str, width_px: int, height_px: int
) -> None:
    image = _texture(kind, 1, width_px=width_px, height_px=height_px)
    assert image.shape == (height_px, width_px, 3)
    assert image.dtype == np.uint8


def test_numpy_scalars_are_accepted_as_sizes_and_lengths() -> None:
    pipe = pipe_texture(
        np.random.default_rng(2),
        width_px=np.int64(32),
        height_px=np.int32(16),
        length_m=np.float64(0.5),
        circumference_m=np.float32(0.6),
    )
    node = node_texture(
        np.random.default_rng(2), np.int64(16), np.int64(24), radius_m=np.float64(0.1)
    )
    assert pipe.shape == (16, 32, 3)
    assert node.shape == (24, 16, 3)


@pytest.mark.parametrize(
    ("draw", "width_px", "height_px"),
    [
        (pipe_texture, 16, 16),
        (node_texture, 16, 16),
        (pipe_texture, 8192, 16),
        (node_texture, 16, 8192),
    ],
)
def test_size_limits_are_inclusive(
    draw: Callable[..., np.ndarray], width_px: int, height_px: int
) -> None:
    image = draw(np.random.default_rng(0), width_px=width_px, height_px=height_px)
    assert image.shape == (height_px, width_px, 3)
    assert image.std() > 5.0


@pytest.mark.parametrize("kind", ["pipe", "node"])
@pytest.mark.parametrize("material", MATERIALS)
def test_textures_have_contrast_and_a_sane_exposure(kind: str, material: str) -> None:
    for seed in range(3):
        image = _texture(kind, seed, material=material)
        gray = _gray(image)
        assert gray.std() > 10.0, seed
        assert np.percentile(gray, 95) - np.percentile(gray, 5) > 35.0, seed
        assert 80.0 <= gray.mean() <= 160.0, seed
        assert np.mean((image == 0) | (image == 255)) < 0.01, seed


@pytest.mark.parametrize("kind", ["pipe", "node"])
def test_explicit_material_sets_the_colour_family(kind: str) -> None:
    for seed in range(3):
        clay = _red_share(_texture(kind, seed, material="clay"))
        concrete = _red_share(_texture(kind, seed, material="concrete"))
        assert clay > concrete + 0.08, seed


@pytest.mark.parametrize("kind", ["pipe", "node"])
def test_no_material_draws_several_families_from_the_generator(kind: str) -> None:
    shares = [_red_share(_texture(kind, seed, width_px=32, height_px=32)) for seed in range(10)]
    assert any(s > 0.45 for s in shares)  # clay
    assert any(s < 0.42 for s in shares)  # concrete or cast iron


def test_pipe_texture_wraps_seamlessly_around_the_circumference() -> None:
    grays = [_gray(_texture("pipe", seed)) for seed in range(6)]
    assert _seam_to_step_ratio(grays) < 1.3
    # Control: the same measure on a half (no wrap) sees a seam.
    assert _seam_to_step_ratio([g[: g.shape[0] // 2] for g in grays]) > 1.4


def test_node_texture_wraps_seamlessly_around_the_longitude() -> None:
    # Columns are the longitude; away from the poles, which are blurred along it.
    grays = [_gray(_texture("node", seed, width_px=128))[16:48].T for seed in range(6)]
    assert _seam_to_step_ratio(grays) < 1.3
    assert _seam_to_step_ratio([g[: g.shape[0] // 2] for g in grays]) > 1.4


@pytest.mark.parametrize("material", MATERIALS)
def test_pipe_floor_is_at_both_edge_rows_and_unlike_the_crown(material: str) -> None:
    for seed in range(3):
        image = _texture("pipe", seed, material=material)
        first = _band_rgb(image, 0.0, 0.05)
        last = _band_rgb(image, 0.95, 1.0)
        crown = _band_rgb(image, 0.4, 0.6)
        floors_apart = np.linalg.norm(first - last)
        assert floors_apart < 0.5 * np.linalg.norm(first - crown), seed
        assert floors_apart < 0.5 * np.linalg.norm(last - crown), seed


# Cast-iron sediment is too close to the rusty wall to tell apart by mean colour.
@pytest.mark.parametrize("material", ["concrete", "clay"])
def test_node_sediment_pool_is_at_row_zero(material: str) -> None:
    for seed in range(3):
        image = _texture("node", seed, material=material)
        bottom = _band_rgb(image, 0.0, 0.1)
        equator = _band_rgb(image, 0.4, 0.6)
        top = _band_rgb(image, 0.9, 1.0)
        assert np.linalg.norm(bottom - equator) > 2.0 * np.linalg.norm(top - equator), seed


def test_node_rows_are_smoothed_along_the_longitude_near_the_poles() -> None:
    for seed in range(3):
        gray = _gray(_texture("node", seed))
        steps = np.abs(np.diff(gray, axis=1)).mean(axis=1)
        equator = float(np.median(steps[24:40]))
        assert steps[0] < 0.2 * equator, seed
        assert steps[-1] < 0.2 * equator, seed


BAD_COMMON: list[dict[str, Any]] = [
    {"width_px": 15},
    {"height_px": 15},
    {"width_px": 8193},
    {"height_px": 8193},
    {"width_px": 0},
    {"width_px": -64},
    {"width_px": 64.0},
    {"height_px": True},
    {"width_px": "64"},
    {"material": "steel"},
    {"material": "Clay"},
    {"material": ""},
]
BAD_PIPE = BAD_COMMON + [
    {"length_m": 0.0},
    {"length_m": -1.0},
    {"length_m": float("nan")},
    {"length_m": float("inf")},
    {"length_m": True},
    {"length_m": "1"},
    {"circumference_m": 0},
    {"circumference_m": -0.6},
    {"circumference_m": float("nan")},
]
BAD_NODE = BAD_COMMON + [
    {"radius_m": 0.0},
    {"radius_m": -0.2},
    {"radius_m": float("inf")},
    {"radius_m": None},
]


@pytest.mark.parametrize("kwargs", BAD_PIPE, ids=repr)
def test_pipe_texture_rejects_bad_arguments(kwargs: dict[str, Any]) -> None:
    with pytest.raises(SimError):
        pipe_texture(np.random.default_rng(0), **{**PIPE_PX, **kwargs})


@pytest.mark.parametrize("kwargs", BAD_NODE, ids=repr)
def test_node_texture_rejects_bad_arguments(kwargs: dict[str, Any]) -> None:
    with pytest.raises(SimError):
        node_texture(np.random.default_rng(0), **{**NODE_PX, **kwargs})


@pytest.mark.parametrize("draw", [pipe_texture, node_texture])
# Ids by type: a RandomState's repr holds its address, which differs between the
# workers of a parallel run, and xdist needs every worker to collect the same ids.
@pytest.mark.parametrize(
    "rng", [0, None, np.random.RandomState(0)], ids=["int", "None", "RandomState"]
)
def test_textures_need_a_numpy_generator(draw: Callable[..., np.ndarray], rng: object) -> None:
    with pytest.raises(SimError):
        draw(rng, width_px=16, height_px=16)


@pytest.mark.parametrize("draw", [pipe_texture, node_texture])
def test_rejected_call_draws_nothing_from_the_generator(draw: Callable[..., np.ndarray]) -> None:
    rng = np.random.default_rng(5)
    before = rng.bit_generator.state
    with pytest.raises(SimError):
        draw(rng, width_px=16, height_px=16, material="brick")
    assert rng.bit_generator.state == before
