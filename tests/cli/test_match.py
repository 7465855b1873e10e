"""``pipemap match``: every pair of image sets, as JSON and as a table."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from pipemap.imagesets import load_image_set
from pipemap.localizer import FastConfig, reference_match
from pipemap.localizer.pairwise import pairwise_matches
from pipemap.localizer.presets import (
    ROBUST_FAST,
    ROBUST_HIGHPASS_FRACTION,
    ROBUST_ZOOMS,
)
from tests.cli.common import COUNT, WIDTH_PX, make_set, run, textures, write_set
from tests.conftest import PAPER_SETS

#: The columns of the text table: the keys of a JSON pair but the pinhole rotation,
#: which only ``--json`` reports.
TABLE_COLUMNS = ["a", "b", "similarity", "image_shift", "pixel_shift", "rotation_rad", "same"]
PAIR_KEYS = {*TABLE_COLUMNS, "rotation_pinhole_rad"}


def match_json(argv: list[str], capfd: pytest.CaptureFixture[str]) -> dict[str, object]:
    status, out, err = run(["match", *argv, "--json"], capfd)
    assert status == 0, err
    assert err == ""
    doc = json.loads(out)  # the whole of stdout is one JSON document
    assert isinstance(doc, dict)
    return doc


def test_match_json_pairs_in_argument_order(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    a, b, c = (make_set(tmp_path, name, seed) for name, seed in [("A", 1), ("B", 2), ("C", 3)])
    doc = match_json([str(a), str(b), str(c)], capfd)
    assert set(doc) == {"threshold", "pairs"}
    assert doc["threshold"] == 0.36
    pairs = doc["pairs"]
    assert isinstance(pairs, list)
    assert [(p["a"], p["b"]) for p in pairs] == [
        (str(a), str(b)),
        (str(a), str(c)),
        (str(b), str(c)),
    ]
    for pair in pairs:
        assert set(pair) == PAIR_KEYS
        assert -1.0 <= pair["similarity"] <= 1.0
        assert isinstance(pair["image_shift"], int) and 0 <= pair["image_shift"] < COUNT
        assert abs(pair["pixel_shift"]) <= WIDTH_PX / 2
        assert -math.pi < pair["rotation_rad"] <= math.pi
        assert pair["same"] is (pair["similarity"] >= doc["threshold"])
        # Unrelated random textures: nothing to recognise.
        assert pair["same"] is False


def rolled_pair(tmp_path: Path) -> tuple[Path, Path]:
    """A set and the same images with the sweep started two images later.

    ``np.roll(images, 2)`` makes image i of B equal to image (i - 2) mod N of A, so
    image j of A is image (j + 2) mod N of B: with similarity.py's definition
    (image j of A against image (j + k) mod N of B) the best offset is k = 2.
    """
    images = textures(11)
    rolled = list(np.roll(np.stack(images), 2, axis=0))
    assert np.array_equal(rolled[3], images[1])  # B[i] == A[(i - 2) mod N]
    return write_set(tmp_path / "A", images), write_set(tmp_path / "B", rolled)


@pytest.mark.parametrize(
    "extra",
    [
        [],
        ["--downsample", "4"],
        ["--every-offset"],
        ["--reference"],
        ["--zoom", "1.15,1.3", "--highpass", "0.125"],
    ],
    ids=["fast", "downsample-4", "every-offset", "reference", "zoom-highpass"],
)
def test_match_cyclic_permutation(
    extra: list[str], tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    a, b = rolled_pair(tmp_path)
    (pair,) = match_json([str(a), str(b), *extra], capfd)["pairs"]
    assert pair["image_shift"] == 2
    assert pair["similarity"] > 0.95
    assert pair["same"] is True
    assert abs(pair["pixel_shift"]) < 1.0
    # I * 2*pi/N + P * fov/W with I = 2, N = 6, P ~ 0.
    assert pair["rotation_rad"] == pytest.approx(2 * 2 * math.pi / COUNT, abs=0.02)


def test_match_cyclic_permutation_other_way_round(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    a, b = rolled_pair(tmp_path)
    # Image j of B is image (j - 2) mod N of A: k = N - 2, a rotation of -2*pi/3.
    (pair,) = match_json([str(b), str(a)], capfd)["pairs"]
    assert pair["image_shift"] == COUNT - 2
    assert pair["similarity"] > 0.95
    assert pair["same"] is True
    assert pair["rotation_rad"] == pytest.approx(-2 * 2 * math.pi / COUNT, abs=0.02)


def test_match_threshold_decides_same(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    a = make_set(tmp_path, "A", seed=1)
    c = make_set(tmp_path, "C", seed=3)
    (default,) = match_json([str(a), str(c)], capfd)["pairs"]
    assert default["same"] is False
    lenient = match_json([str(a), str(c), "--threshold", "-1"], capfd)
    assert lenient["threshold"] == -1.0
    (pair,) = lenient["pairs"]
    assert pair["same"] is True  # every similarity is at least -1
    assert pair["similarity"] == default["similarity"]  # the threshold decides only "same"


def test_match_table(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    a, r = rolled_pair(tmp_path)
    c = make_set(tmp_path, "C", seed=3)
    status, out, err = run(["match", str(a), str(r), str(c)], capfd)
    assert status == 0, err
    assert err == ""
    lines = out.splitlines()
    assert lines[0].split() == TABLE_COLUMNS
    rows = [line.split() for line in lines[1:4]]
    assert [(row[0], row[1]) for row in rows] == [
        (str(a), str(r)),
        (str(a), str(c)),
        (str(r), str(c)),
    ]
    assert rows[0][3] == "2" and rows[0][-1] == "yes"
    assert rows[1][-1] == "no" and rows[2][-1] == "no"
    assert lines[4:] == ["threshold 0.36; 3 pairs"]


#: A pair of the paper's sets (different junctions) on which every similarity flag
#: moves the result, ``--every-offset`` included: under ``--robust`` only the two most
#: promising offsets are refined, and here the best one is not among them.
FLAG_PAIR = ("1_active", "4")


def _api_pair(config: FastConfig, every_offset: bool = False) -> tuple[float, int]:
    sets = [load_image_set(PAPER_SETS / name) for name in FLAG_PAIR]
    match = pairwise_matches(sets, config, every_offset=every_offset)[(0, 1)]
    return round(match.similarity, 6), match.image_shift  # as the JSON rounds it


_ROBUST = FastConfig(
    zooms=ROBUST_ZOOMS, highpass_fraction=ROBUST_HIGHPASS_FRACTION, baseline=True, **ROBUST_FAST
)


@pytest.mark.parametrize(
    ("flags", "config", "every_offset", "without"),
    [
        (["--downsample", "2"], FastConfig(fine_downsample=2), False, FastConfig()),
        (["--highpass", "0.125"], FastConfig(highpass_fraction=0.125), False, FastConfig()),
        (["--zoom", "1.15,1.3"], FastConfig(zooms=(1.15, 1.3)), False, FastConfig()),
        (["--baseline"], FastConfig(baseline=True), False, FastConfig()),
        (["--robust"], _ROBUST, False, FastConfig()),
        (["--robust", "--every-offset"], _ROBUST, True, _ROBUST),
    ],
    ids=["downsample", "highpass", "zoom", "baseline", "robust", "every-offset"],
)
def test_each_similarity_flag_reaches_the_matcher(
    flags: list[str],
    config: FastConfig,
    every_offset: bool,
    without: FastConfig,
    capfd: pytest.CaptureFixture[str],
) -> None:
    """The command's pair is the library's with the flag's setting, and not the one
    without the flag: a flag the command dropped would fail here."""
    dirs = [str(PAPER_SETS / name) for name in FLAG_PAIR]
    (pair,) = match_json([*dirs, *flags], capfd)["pairs"]
    wanted = _api_pair(config, every_offset)
    assert (pair["similarity"], pair["image_shift"]) == wanted
    assert wanted != _api_pair(without)


def test_the_field_of_view_flag_turns_the_rotation(capfd: pytest.CaptureFixture[str]) -> None:
    """``--fov-deg`` sets how far a pixel of shift turns: the rotations are the
    library's for sets of that field of view, not those of the default 80 degrees."""
    dirs = [str(PAPER_SETS / name) for name in ("1", "1_noise")]
    (pair,) = match_json([*dirs, "--fov-deg", "60"], capfd)["pairs"]
    sets = [load_image_set(d, fov_rad=math.radians(60.0)) for d in dirs]
    wanted = pairwise_matches(sets)[(0, 1)]
    default = pairwise_matches([load_image_set(d) for d in dirs])[(0, 1)]
    assert pair["rotation_rad"] == round(wanted.rotation_rad, 6)
    assert pair["rotation_pinhole_rad"] == round(wanted.rotation_pinhole_rad, 6)
    assert round(default.rotation_rad, 6) != pair["rotation_rad"]


def test_the_kept_part_flag_sets_what_is_matched(capfd: pytest.CaptureFixture[str]) -> None:
    """``--keep-top`` sets how much of each image, from the top, is matched."""
    dirs = [str(PAPER_SETS / name) for name in FLAG_PAIR]
    (pair,) = match_json([*dirs, "--keep-top", "0.75"], capfd)["pairs"]
    sets = [load_image_set(d, keep_top_fraction=0.75) for d in dirs]
    wanted = pairwise_matches(sets)[(0, 1)]
    default = pairwise_matches([load_image_set(d) for d in dirs])[(0, 1)]
    assert pair["similarity"] == round(wanted.similarity, 6)
    assert round(default.similarity, 6) != pair["similarity"]


def test_the_reference_flag_runs_the_reference(capfd: pytest.CaptureFixture[str]) -> None:
    """``--reference`` is the paper's algorithm as published, not the fast path: on
    this pair the two agree on the similarity to 1e-8 but not on the peak's sub-pixel
    shift (41.33 px against 41.43)."""
    dirs = [str(PAPER_SETS / name) for name in FLAG_PAIR]
    (pair,) = match_json([*dirs, "--reference"], capfd)["pairs"]
    sets = [load_image_set(d) for d in dirs]
    wanted = reference_match(*sets)
    fast = pairwise_matches(sets)[(0, 1)]
    assert (pair["similarity"], pair["pixel_shift"]) == (
        round(wanted.similarity, 6),
        round(wanted.pixel_shift, 6),
    )
    assert round(fast.pixel_shift, 6) != pair["pixel_shift"]
