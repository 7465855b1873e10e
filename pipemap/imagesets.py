"""Image-set folders in the paper's layout: ``camera_image1..N`` plus an optional ``info.txt``.

Reading files is the application's job, not the localizer's: this module turns a
folder into a :class:`localizer.ImageSet` and names the offending path in every
error it raises.

``info.txt`` holds ground truth (the camera pose, the true node) and is never read
into an image set. What the robot itself knows about a sweep goes in an optional
``sweep.txt``: ``camera_angle: A``, the camera's angle at the first image relative
to the robot's heading in radians (0, straight ahead, when the file is absent); and,
from an autonomous run, ``exits: A,B,...`` (the pipes the exit scan found, relative
to the robot's heading), ``departure: A`` (the pipe it left by) and
``odometer_m: D`` (the distance it had driven), which give the map its ports; and
``lighting: lamp|even``, how the sweep was lit: under the robot's own lamp, ``match``
and ``map`` normalise each image's illumination as a replay does (docs/lighting.md).
"""

from __future__ import annotations

import math
import os
import re
import secrets
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from pipemap.errors import InputError, WriteError
from pipemap.localizer import DEFAULT_FOV_RAD, DEFAULT_KEEP_TOP_FRACTION, ImageSet
from pipemap.pngcheck import MAX_IMAGE_SIDE_PX, PNG_SIGNATURE, image_size, png_problem

__all__ = [
    "IMAGE_SUFFIXES",
    "RobotNotes",
    "load_image_set",
    "lamp_lit",
    "load_image_sets",
    "read_info",
    "read_robot_notes",
    "write_image_set",
]

#: Image formats accepted in a set folder (those OpenCV decodes everywhere).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm")
_NAME = re.compile(r"^camera_image(\d+)$")


def _image_files(folder: Path) -> list[Path]:
    found: dict[int, Path] = {}
    for path in folder.iterdir():
        match = _NAME.match(path.stem)
        if match is None or path.suffix.lower() not in IMAGE_SUFFIXES or not path.is_file():
            continue
        index = int(match.group(1))
        if index in found:
            raise InputError(
                f"{folder}: two files for image {index}: {found[index].name}, {path.name}"
            )
        found[index] = path
    if not found:
        raise InputError(f"{folder}: no camera_image1..N image files")
    expected = list(range(1, len(found) + 1))
    if sorted(found) != expected:
        missing = sorted(set(expected) - set(found))
        raise InputError(f"{folder}: images are not numbered 1..{len(found)} (missing {missing})")
    return [found[i] for i in expected]


def _read_gray(path: Path) -> np.ndarray:
    if not path.is_file():  # a FIFO or a device would block the read, or never end
        raise InputError(f"{path}: not a regular file")
    data = path.read_bytes()
    # libjpeg decodes a truncated JPEG with only a warning: demand the end marker.
    if path.suffix.lower() in (".jpg", ".jpeg") and not data.rstrip(b"\0").endswith(b"\xff\xd9"):
        raise InputError(f"{path}: truncated or corrupt JPEG image")
    if not data:
        raise InputError(f"{path}: empty file, not an image")
    size = image_size(data)
    if size is not None and max(size) > MAX_IMAGE_SIDE_PX:
        raise InputError(
            f"{path}: an image of {size[0]}x{size[1]} pixels; pipemap reads images of at "
            f"most {MAX_IMAGE_SIDE_PX} pixels a side"
        )
    # libpng reports a damaged PNG on stderr itself: check the chunks and their CRCs first.
    if data.startswith(PNG_SIGNATURE):
        problem = png_problem(data)
        if problem:
            raise InputError(f"{path}: {problem}")
    try:
        image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_GRAYSCALE)
    except cv2.error:  # OpenCV's own checks (a size past its limit, in another format)
        image = None
    if image is None or image.size == 0 or max(image.shape) > MAX_IMAGE_SIDE_PX:
        raise InputError(f"{path}: not a readable image")
    return image


def load_image_set(
    folder: str | Path, fov_rad: float | None = None, keep_top_fraction: float | None = None
) -> ImageSet:
    """Read the grayscale images of one set folder, in sweep order."""
    path = Path(folder)
    if not path.exists():
        raise InputError(f"{path}: no such folder")
    if not path.is_dir():
        raise InputError(f"{path}: not a folder")
    images: list[np.ndarray] = []
    for file in _image_files(path):
        try:
            image = _read_gray(file)
        except OSError as exc:
            raise InputError(f"{file}: cannot read ({exc.strerror})") from exc
        if images and image.shape != images[0].shape:
            raise InputError(
                f"{file}: image is {image.shape[1]}x{image.shape[0]}, the set's first is "
                f"{images[0].shape[1]}x{images[0].shape[0]}"
            )
        images.append(image)
    return ImageSet(
        np.stack(images),
        fov_rad=DEFAULT_FOV_RAD if fov_rad is None else fov_rad,
        keep_top_fraction=DEFAULT_KEEP_TOP_FRACTION
        if keep_top_fraction is None
        else keep_top_fraction,
        camera_angle_rad=_camera_angle(path),
    )


def _number(path: Path, key: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{path}: {key} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise InputError(f"{path}: {key} {text!r} is not finite")
    return value


def _camera_angle(folder: Path) -> float:
    """``camera_angle`` from the folder's ``sweep.txt``; 0.0 without one."""
    path = folder / "sweep.txt"
    if not path.is_file():
        return 0.0
    return _number(path, "camera_angle", _key_values(path).get("camera_angle", "0"))


@dataclass(frozen=True)
class RobotNotes:
    """What the robot noted at a sweep besides its images (from ``sweep.txt``)."""

    exits_rad: tuple[float, ...] | None = None
    departure_rad: float | None = None
    odometer_m: float | None = None
    #: ``"lamp"`` (lit by the robot's own lamp) or ``"even"``; ``None``: not said.
    lighting: str | None = None


#: The values of ``lighting`` in ``sweep.txt``.
LIGHTINGS = ("lamp", "even")


def read_robot_notes(folder: str | Path) -> RobotNotes:
    """The exits, departure and odometer of a set's ``sweep.txt`` (each ``None`` when
    absent)."""
    path = Path(folder) / "sweep.txt"
    if not path.is_file():
        return RobotNotes()
    values = _key_values(path)
    exits = None
    if "exits" in values:
        text = values["exits"]
        exits = tuple(_number(path, "exits", t.strip()) for t in text.split(",") if t.strip())
    departure = values.get("departure")
    odometer = values.get("odometer_m")
    lighting = values.get("lighting")
    if lighting is not None and lighting not in LIGHTINGS:
        raise InputError(f"{path}: lighting must be lamp or even, got {lighting!r}")
    return RobotNotes(
        exits,
        None if departure is None else _number(path, "departure", departure),
        None if odometer is None else _number(path, "odometer_m", odometer),
        lighting,
    )


def lamp_lit(folders: Sequence[str | Path]) -> bool:
    """Whether the sets were lit by the robot's lamp, as their ``sweep.txt`` say:
    true when some say ``lighting: lamp`` and none ``even`` (a folder that says
    nothing is taken as lit as the others). Folders that disagree are refused: they
    need ``--illumination``."""
    said = {str(f): read_robot_notes(f).lighting for f in folders}
    lamp = [f for f, v in said.items() if v == "lamp"]
    even = [f for f, v in said.items() if v == "even"]
    if lamp and even:
        raise InputError(
            f"{lamp[0]} is lamp-lit but {even[0]} evenly lit (sweep.txt): give "
            "--illumination lamp or even to compare them"
        )
    return bool(lamp)


def _key_values(path: Path) -> dict[str, str]:
    values: dict[str, str] = {}
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        key, sep, value = line.partition(":")
        if sep and value.strip():
            values[key.strip()] = value.strip()
    return values


def load_image_sets(
    folders: Sequence[str | Path],
    fov_rad: float | None = None,
    keep_top_fraction: float | None = None,
) -> list[ImageSet]:
    """Read several set folders; they must agree in image count and size."""
    sets: list[ImageSet] = []
    for folder in folders:
        image_set = load_image_set(folder, fov_rad, keep_top_fraction)
        if sets and image_set.images.shape != sets[0].images.shape:
            first, this = sets[0], image_set
            raise InputError(
                f"{folder}: {this.count} images of {this.width}x{this.height}, but "
                f"{folders[0]} has {first.count} of {first.width}x{first.height}"
            )
        sets.append(image_set)
    return sets


def read_info(folder: str | Path) -> dict[str, str]:
    """The ``key: value`` lines of a set's ``info.txt`` ({} if it has none).

    Used for ground truth by tests and tools; the localizer never sees it.
    """
    path = Path(folder) / "info.txt"
    return _key_values(path) if path.is_file() else {}


def write_image_set(
    folder: str | Path,
    images: np.ndarray,
    info: dict[str, str],
    camera_angle_rad: float = 0.0,
    notes: RobotNotes | None = None,
) -> None:
    """Write one sweep in the paper's layout: ``camera_image1..N.png`` and ``info.txt``.

    ``images`` is (N, H, W, 3) RGB or (N, H, W) gray, uint8. ``info`` lines are written
    as ``key: value`` in the given order. A non-zero camera angle at the first image,
    and the robot's ``notes``, go to ``sweep.txt``. The folder must not exist yet.
    """
    path = Path(folder)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists():
        raise InputError(f"{path}: exists already")
    # Written whole or not at all: in a temporary folder beside it, renamed when done.
    partial = path.with_name(f".{path.name}.{secrets.token_hex(4)}.partial")
    try:
        partial.mkdir()
        _write_files(partial, images, info, camera_angle_rad, notes)
        os.rename(partial, path)
    except OSError as exc:
        raise WriteError(f"{path}: cannot write ({exc.strerror or exc})") from None
    finally:
        shutil.rmtree(partial, ignore_errors=True)


def _write_files(
    path: Path,
    images: np.ndarray,
    info: dict[str, str],
    camera_angle_rad: float,
    notes: RobotNotes | None,
) -> None:
    for i, image in enumerate(images, start=1):
        bgr = cv2.cvtColor(image, cv2.COLOR_RGB2BGR) if image.ndim == 3 else image
        # Encoded in memory and written by Python: a full disk is an OSError here,
        # never libpng's own complaint on standard error.
        done, png = cv2.imencode(".png", bgr)
        if not done:
            raise InputError(f"{path}: cannot encode camera_image{i}.png")
        (path / f"camera_image{i}.png").write_bytes(png.tobytes())
    lines = [f"{key}: {value}" for key, value in info.items()]
    (path / "info.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    lines = []
    if camera_angle_rad != 0.0:
        lines.append(f"camera_angle: {camera_angle_rad!r}")
    if notes is not None and notes.exits_rad is not None:
        lines.append(f"exits: {','.join(repr(float(e)) for e in notes.exits_rad)}")
    if notes is not None and notes.lighting is not None:
        lines.append(f"lighting: {notes.lighting}")
    if notes is not None and notes.departure_rad is not None:
        lines.append(f"departure: {float(notes.departure_rad)!r}")
    if notes is not None and notes.odometer_m is not None:
        lines.append(f"odometer_m: {float(notes.odometer_m)!r}")
    if lines:
        (path / "sweep.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
