"""The ``pipemap`` command, driven through ``pipemap.cli.main`` and as a subprocess.

Every fixture image set is written into ``tmp_path`` by this module: smooth random
textures (blurred noise, one seed per set) large enough that the matcher's default
8x area downsampling still leaves a meaningful correlation. Bad inputs must end with
exit status 2 and exactly one ``pipemap: error:`` line naming the offending path or
value, never a traceback; stderr is captured at the file-descriptor level so that
warnings printed by native libraries (OpenCV, libpng, libjpeg) count too.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipemap.cli import main
from pipemap.localizer import wrap_angle_rad
from tests.conftest import PaperSet

ROOT = Path(__file__).resolve().parents[1]
COUNT = 6
WIDTH_PX = 128
HEIGHT_PX = 96
PAIR_KEYS = {
    "a",
    "b",
    "similarity",
    "image_shift",
    "pixel_shift",
    "rotation_rad",
    "rotation_pinhole_rad",
    "same",
}


# ---------------------------------------------------------------- fixture writers


def textures(
    seed: int, count: int = COUNT, width_px: int = WIDTH_PX, height_px: int = HEIGHT_PX
) -> list[np.ndarray]:
    """``count`` smooth random uint8 textures drawn from one seed."""
    rng = np.random.default_rng(seed)
    images = []
    for _ in range(count):
        noise = rng.random((height_px, width_px), dtype=np.float32)
        smooth = cv2.GaussianBlur(noise, (0, 0), 2.0)
        span = float(smooth.max() - smooth.min())
        images.append(np.round(255.0 * (smooth - smooth.min()) / span).astype(np.uint8))
    return images


def write_set(folder: Path, images: Sequence[np.ndarray], suffix: str = ".png") -> Path:
    """Write ``camera_image1..N`` into ``folder`` (created) and return it."""
    folder.mkdir(parents=True, exist_ok=True)
    for number, image in enumerate(images, start=1):
        assert cv2.imwrite(str(folder / f"camera_image{number}{suffix}"), image)
    return folder


def make_set(tmp_path: Path, name: str, seed: int, **kwargs: int) -> Path:
    """A fresh random image set folder ``tmp_path/name``."""
    return write_set(tmp_path / name, textures(seed, **kwargs))


# ---------------------------------------------------------------- running the command


def run(argv: list[str], capfd: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    """Run ``pipemap`` in-process; returns (exit status, stdout, stderr).

    argparse ends a bad command line with ``SystemExit``, the command's own
    errors return a status: both are an exit status for the user.
    """
    try:
        status = main(argv)
    except SystemExit as exc:
        status = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    out, err = capfd.readouterr()
    return status, out, err


def run_subprocess(argv: list[str], cwd: Path) -> subprocess.CompletedProcess[str]:
    """Run ``python -m pipemap`` in a fresh interpreter, the repository on PYTHONPATH."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *argv],
        cwd=cwd,  # not the repository: it must be found through PYTHONPATH
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def assert_one_error(status: int, out: str, err: str, *names: str) -> str:
    """Exit 2, nothing on stdout, one ``pipemap: error:`` line naming ``names``."""
    assert "Traceback" not in err, err
    assert status == 2, (status, err)
    lines = err.splitlines()
    assert len(lines) == 1, f"expected one line on stderr, got {len(lines)}:\n{err}"
    line = lines[0]
    assert line.startswith("pipemap: error:"), line
    for name in names:
        assert name in line, f"{name!r} not named in {line!r}"
    assert out == "", f"stdout not empty on error: {out!r}"
    return line


# ---------------------------------------------------------------- bad input: files and folders


def test_missing_folder(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = make_set(tmp_path, "a", seed=1)
    missing = tmp_path / "nowhere"
    status, out, err = run(["match", str(good), str(missing)], capfd)
    assert_one_error(status, out, err, str(missing))


@pytest.mark.parametrize("value", ["east", "nan", "inf"])
def test_bad_camera_angle_in_sweep_txt(
    value: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    good = make_set(tmp_path, "a", seed=1)
    bad = make_set(tmp_path, "b", seed=2)
    (bad / "sweep.txt").write_text(f"camera_angle: {value}\n")
    status, out, err = run(["match", str(good), str(bad)], capfd)
    assert_one_error(status, out, err, str(bad / "sweep.txt"), "camera_angle")


def test_sweep_txt_sets_the_camera_angle_and_info_txt_is_not_read(tmp_path: Path) -> None:
    from pipemap.imagesets import load_image_set, read_info, write_image_set

    images = np.stack(textures(4))
    write_image_set(tmp_path / "turned", images, {"node": "A", "yaw": "1.0"}, 0.25)
    write_image_set(tmp_path / "ahead", images, {"node": "A", "yaw": "1.0"})
    assert load_image_set(tmp_path / "turned").camera_angle_rad == 0.25
    assert load_image_set(tmp_path / "ahead").camera_angle_rad == 0.0
    assert not (tmp_path / "ahead" / "sweep.txt").exists()
    assert read_info(tmp_path / "turned") == {"node": "A", "yaw": "1.0"}


def test_path_is_a_file(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = make_set(tmp_path, "a", seed=1)
    a_file = tmp_path / "notes.txt"
    a_file.write_text("not an image set\n")
    status, out, err = run(["match", str(good), str(a_file)], capfd)
    assert_one_error(status, out, err, str(a_file))


def test_folder_without_images(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = make_set(tmp_path, "a", seed=1)
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "info.txt").write_text("junction: 3\n")  # not an image: must not count
    status, out, err = run(["match", str(good), str(empty)], capfd)
    assert_one_error(status, out, err, str(empty))


def test_images_not_numbered_contiguously(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    good = make_set(tmp_path, "a", seed=1)
    gappy = make_set(tmp_path, "gappy", seed=2)
    # 1, 2, 3, 5, 6, 7: six images, but no camera_image4.
    (gappy / "camera_image4.png").rename(gappy / "camera_image7.png")
    status, out, err = run(["match", str(good), str(gappy)], capfd)
    assert_one_error(status, out, err, str(gappy), "4")


def test_corrupt_image(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = make_set(tmp_path, "a", seed=1)
    bad = make_set(tmp_path, "bad", seed=2)
    corrupt = bad / "camera_image3.png"
    corrupt.write_bytes(np.random.default_rng(3).bytes(4096))
    status, out, err = run(["match", str(good), str(bad)], capfd)
    assert_one_error(status, out, err, str(corrupt))


def test_truncated_jpeg(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = write_set(tmp_path / "a", textures(1), suffix=".jpg")
    bad = write_set(tmp_path / "bad", textures(2), suffix=".jpg")
    truncated = bad / "camera_image2.jpg"
    data = truncated.read_bytes()
    truncated.write_bytes(data[: len(data) // 2])
    status, out, err = run(["match", str(good), str(bad)], capfd)
    assert_one_error(status, out, err, str(truncated))


def test_truncated_png(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = make_set(tmp_path, "a", seed=1)
    bad = make_set(tmp_path, "bad", seed=2)
    truncated = bad / "camera_image5.png"
    data = truncated.read_bytes()
    truncated.write_bytes(data[: len(data) // 2])
    status, out, err = run(["match", str(good), str(bad)], capfd)
    assert_one_error(status, out, err, str(truncated))


def test_wrong_image_size_inside_a_set(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = make_set(tmp_path, "a", seed=1)
    bad = make_set(tmp_path, "bad", seed=2)
    odd = bad / "camera_image4.png"
    assert cv2.imwrite(str(odd), textures(9, count=1, width_px=WIDTH_PX + 32)[0])
    status, out, err = run(["match", str(good), str(bad)], capfd)
    assert_one_error(status, out, err, str(odd))


def test_sets_with_different_image_counts(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    six = make_set(tmp_path, "six", seed=1)
    five = make_set(tmp_path, "five", seed=2, count=5)
    status, out, err = run(["match", str(six), str(five)], capfd)
    line = assert_one_error(status, out, err, str(five), str(six))
    assert "5" in line and "6" in line


def test_sets_with_different_image_sizes(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    small = make_set(tmp_path, "small", seed=1)
    wide = make_set(tmp_path, "wide", seed=2, width_px=160)
    status, out, err = run(["map", str(small), str(wide)], capfd)
    line = assert_one_error(status, out, err, str(wide), str(small))
    assert "160" in line


# ---------------------------------------------------------------- bad input: the command line


def test_unknown_flag(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = make_set(tmp_path, "a", seed=1)
    status, out, err = run(["match", str(good), "--bogus"], capfd)
    assert_one_error(status, out, err, "--bogus")


@pytest.mark.parametrize("value", ["2", "abc", "nan", "-1.5"])
def test_bad_threshold(value: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = make_set(tmp_path, "a", seed=1)
    status, out, err = run(["match", str(good), "--threshold", value], capfd)
    line = assert_one_error(status, out, err, "--threshold")
    assert line.rstrip("'\"").endswith(value), line  # the bad value, as typed


@pytest.mark.parametrize(
    ("flag", "value"),
    [
        ("--downsample", "0"),
        ("--fov-deg", "400"),
        ("--keep-top", "0"),
        ("--zoom", "1.2,0.9"),
        ("--zoom", "x"),
        ("--highpass", "2"),
    ],
)
def test_bad_matching_option(
    flag: str, value: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    good = make_set(tmp_path, "a", seed=1)
    status, out, err = run(["map", str(good), flag, value], capfd)
    line = assert_one_error(status, out, err, flag)
    assert line.endswith(value), line


def test_no_command(capfd: pytest.CaptureFixture[str]) -> None:
    status, out, err = run([], capfd)
    assert_one_error(status, out, err, "COMMAND")


def test_command_without_folders(capfd: pytest.CaptureFixture[str]) -> None:
    status, out, err = run(["map"], capfd)
    assert_one_error(status, out, err, "DIR")


def test_help_exits_zero(capfd: pytest.CaptureFixture[str]) -> None:
    status, out, err = run(["--help"], capfd)
    assert status == 0
    assert out.startswith("usage: pipemap")
    assert "match" in out and "map" in out
    assert err == ""


def test_version(capfd: pytest.CaptureFixture[str]) -> None:
    from pipemap import __version__

    status, out, err = run(["--version"], capfd)
    assert status == 0
    assert out.strip() == f"pipemap {__version__}"


# ---------------------------------------------------------------- as a real process


@pytest.mark.parametrize("case", ["missing", "corrupt", "threshold"])
def test_subprocess_error_has_no_traceback(case: str, tmp_path: Path) -> None:
    good = make_set(tmp_path, "a", seed=1)
    if case == "missing":
        named = str(tmp_path / "nowhere")
        argv = ["match", str(good), named]
    elif case == "corrupt":
        bad = make_set(tmp_path, "bad", seed=2)
        (bad / "camera_image3.png").write_bytes(np.random.default_rng(3).bytes(4096))
        named = str(bad / "camera_image3.png")
        argv = ["map", str(good), str(bad)]
    else:
        named = "abc"
        argv = ["match", str(good), "--threshold", named]
    done = run_subprocess(argv, cwd=tmp_path)
    assert_one_error(done.returncode, done.stdout, done.stderr, named)


def test_subprocess_match_json(tmp_path: Path) -> None:
    a = make_set(tmp_path, "a", seed=1)
    b = make_set(tmp_path, "b", seed=2)
    done = run_subprocess(["match", str(a), str(b), "--json"], cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    doc = json.loads(done.stdout)
    assert [(p["a"], p["b"]) for p in doc["pairs"]] == [(str(a), str(b))]


# ---------------------------------------------------------------- match


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
    assert lines[0].split() == [
        "a",
        "b",
        "similarity",
        "image_shift",
        "pixel_shift",
        "rotation_rad",
        "same",
    ]
    rows = [line.split() for line in lines[1:4]]
    assert [(row[0], row[1]) for row in rows] == [
        (str(a), str(r)),
        (str(a), str(c)),
        (str(r), str(c)),
    ]
    assert rows[0][3] == "2" and rows[0][-1] == "yes"
    assert rows[1][-1] == "no" and rows[2][-1] == "no"
    assert lines[4:] == ["threshold 0.36; 3 pairs"]


# ---------------------------------------------------------------- map


def map_set_triple(tmp_path: Path) -> list[str]:
    """A, B, then A again (a copy in its own folder): new, new, known."""
    a = make_set(tmp_path, "A", seed=1)
    b = make_set(tmp_path, "B", seed=2)
    again = make_set(tmp_path, "A2", seed=1)
    return [str(a), str(b), str(again)]


def test_map_json(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    dirs = map_set_triple(tmp_path)
    status, out, err = run(["map", *dirs, "--json"], capfd)
    assert status == 0, err
    assert err == ""
    doc = json.loads(out)
    # Image folders without the robot's exit scans: no ports.
    assert doc["nodes"] == [{"id": 0, "ports": []}, {"id": 1, "ports": []}]
    assert doc["edges"] == [
        {"u": 0, "u_port": None, "v": 1, "v_port": None, "label": 1, "length_m": None}
    ]
    visits = doc["visits"]
    assert [v["set"] for v in visits] == dirs
    assert [v["known"] for v in visits] == [False, False, True]
    assert [v["node"] for v in visits] == [0, 1, 0]
    assert visits[2]["candidate"] == 0
    assert visits[2]["similarity"] > 0.95
    assert visits[2]["image_shift"] == 0


def test_map_allow_repeat_lets_a_set_be_the_junction_before_it(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    a = make_set(tmp_path, "A", seed=1)
    again = make_set(tmp_path, "A2", seed=1)
    status, out, err = run(["map", str(a), str(again), "--json"], capfd)
    assert status == 0, err
    assert [v["node"] for v in json.loads(out)["visits"]] == [0, 1]  # a pipe joins two
    status, out, err = run(["map", str(a), str(again), "--json", "--allow-repeat"], capfd)
    assert status == 0, err
    doc = json.loads(out)
    assert [v["node"] for v in doc["visits"]] == [0, 0]  # the paper's rule: a self-loop
    assert [(e["u"], e["v"], e["label"]) for e in doc["edges"]] == [(0, 0, 1)]


def test_map_is_deterministic(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    dirs = map_set_triple(tmp_path)
    first = run(["map", *dirs, "--json"], capfd)
    second = run(["map", *dirs, "--json"], capfd)
    assert first[0] == second[0] == 0
    assert first[1] != ""
    assert first[1].encode() == second[1].encode()


def test_map_table(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    dirs = map_set_triple(tmp_path)
    status, out, err = run(["map", *dirs], capfd)
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].split() == ["set", "node", "known", "similarity", "margin", "rotation"]
    rows = [line.split() for line in lines[1:4]]
    assert [(row[0], row[1], row[2]) for row in rows] == [
        (dirs[0], "0", "no"),
        (dirs[1], "1", "no"),
        (dirs[2], "0", "yes"),
    ]
    # The rotation of the known visit, as --json reports it; none for new junctions.
    assert [row[5] for row in rows[:2]] == ["-", "-"]
    doc = json.loads(run(["map", *dirs, "--json"], capfd)[1])
    known = doc["visits"][2]
    rotation = known["rotation_two_view_rad"]
    rotation = known["rotation_rad"] if rotation is None else rotation
    assert float(rows[2][5]) == pytest.approx(rotation, abs=5e-5)
    assert lines[4:] == ["2 nodes; edges: 0-1 (1)"]


def test_robust_preset_fills_in_its_settings_and_threshold() -> None:
    from pipemap.cli.localizer_options import apply_presets, fast_config
    from pipemap.cli.parser import build_parser
    from pipemap.localizer.presets import (
        ROBUST_HIGHPASS_FRACTION,
        ROBUST_THRESHOLD,
        ROBUST_ZOOMS,
    )

    args = build_parser().parse_args(["score", "run.mcap", "--robust"])
    apply_presets(args)
    config = fast_config(args)
    assert (config.zooms, config.highpass_fraction, config.baseline) == (
        ROBUST_ZOOMS,
        ROBUST_HIGHPASS_FRACTION,
        True,
    )
    assert args.threshold == ROBUST_THRESHOLD
    # Explicit options win; without --robust the paper's settings stand.
    args = build_parser().parse_args(["map", "d", "--robust", "--threshold", "0.1"])
    apply_presets(args)
    assert args.threshold == 0.1
    args = build_parser().parse_args(["map", "d"])
    apply_presets(args)
    assert args.threshold == 0.36
    assert fast_config(args).baseline is False
    assert fast_config(args).zooms == ()


def test_the_parser_and_its_presets_load_no_heavy_module(tmp_path: Path) -> None:
    """``pipemap --help`` stays instant: the parser takes the presets it shows from
    :mod:`pipemap.localizer.presets` without loading numpy, OpenCV or the simulator."""
    probe = (
        "import sys\n"
        "from pipemap.cli.parser import build_parser\n"
        "build_parser().format_help()\n"
        "heavy = ('numpy', 'cv2', 'scipy', 'pybullet', 'mcap', 'rerun', 'networkx')\n"
        "print(sorted(m for m in heavy if m in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], cwd=tmp_path, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_threshold_help_says_what_decides_at_the_defaults() -> None:
    from pipemap.cli.parser import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for command in ("map", "score", "replay", "record"):
        text = " ".join(sub.choices[command].format_help().split())
        assert "two-view check decides" in text, command


def test_one_rotation_convention(
    paper_sets: dict[str, PaperSet], capfd: pytest.CaptureFixture[str]
) -> None:
    """docs/conventions.md: a rotation of (A, B) is yaw_B - yaw_A. ``match A B`` names
    the pair in argument order; a map visit's pair is (this visit, its candidate)."""
    shared = Path(__file__).resolve().parents[1].parent / "shared" / "paper_imagesets"
    one, two, four = (str(shared / n) for n in ("1", "2", "4"))
    pairs = json.loads(run(["match", two, one, "--json"], capfd)[1])["pairs"]
    visit = json.loads(run(["map", one, four, two, "--json"], capfd)[1])["visits"][2]
    assert visit["candidate"] == 0 and visit["known"]
    assert visit["rotation_rad"] == pairs[0]["rotation_rad"]
    assert visit["rotation_pinhole_rad"] == pairs[0]["rotation_pinhole_rad"]
    # The other order turns the other way; the truth agrees on the sign.
    reverse = json.loads(run(["match", one, two, "--json"], capfd)[1])["pairs"][0]
    assert abs(reverse["rotation_rad"] + pairs[0]["rotation_rad"]) < 0.01
    # The recorded camera yaws (ground truth) agree on the sign and size.
    true_turn = wrap_angle_rad(paper_sets["1"].yaw_rad - paper_sets["2"].yaw_rad)
    assert abs(wrap_angle_rad(visit["rotation_two_view_rad"] - true_turn)) < 0.1


def test_every_command_has_a_runner_and_every_runner_a_command() -> None:
    import importlib

    from pipemap.cli.app import COMMANDS
    from pipemap.cli.parser import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert sorted(COMMANDS) == sorted(sub.choices)
    for command, target in COMMANDS.items():
        module, function = target.split(":")
        assert callable(getattr(importlib.import_module(module), function)), command
