"""What the tests of the ``pipemap`` command share: image-set folders written into
``tmp_path`` (smooth random textures, blurred noise with one seed per set, large enough
that the matcher's default 8x area downsampling still leaves a meaningful
correlation), and the command run in-process through ``pipemap.cli.main`` or as a
subprocess. stderr is captured at the file-descriptor level so that warnings printed
by native libraries (OpenCV, libpng, libjpeg) count too.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipemap.cli import main

ROOT = Path(__file__).resolve().parents[2]
COUNT = 6
WIDTH_PX = 128
HEIGHT_PX = 96


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
