"""``match`` and ``map`` on bad image-set folders: missing, empty, misnumbered,
corrupt or truncated images, sizes and counts that differ. Each must end with exit
status 2 and exactly one ``pipemap: error:`` line naming the offending path, never a
traceback.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.cli.common import WIDTH_PX, assert_one_error, make_set, run, textures, write_set


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


@pytest.mark.parametrize(("suffix", "number"), [(".jpg", 2), (".png", 5)])
def test_truncated_image(
    suffix: str, number: int, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    good = write_set(tmp_path / "a", textures(1), suffix=suffix)
    bad = write_set(tmp_path / "bad", textures(2), suffix=suffix)
    truncated = bad / f"camera_image{number}{suffix}"
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
