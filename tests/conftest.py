"""Shared fixtures: the paper's own image sets, from ``../shared/paper_imagesets``."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import pytest

from pipemap.imagesets import load_image_set, read_info
from pipemap.localizer import ImageSet

REPO = Path(__file__).resolve().parents[1]
PAPER_SETS = Path(
    os.environ.get("PIPEMAP_PAPER_IMAGESETS", REPO.parent / "shared" / "paper_imagesets")
)
#: Two sets show the same junction when their recorded x, y are this close (README there).
SAME_JUNCTION_M = 0.15


@dataclass(frozen=True)
class PaperSet:
    """One of the paper's image sets with its recorded camera pose (ground truth)."""

    name: str
    path: Path
    images: ImageSet
    x_m: float
    y_m: float
    yaw_rad: float

    def same_junction(self, other: PaperSet) -> bool:
        return math.hypot(self.x_m - other.x_m, self.y_m - other.y_m) < SAME_JUNCTION_M


@pytest.fixture(scope="session")
def paper_sets() -> dict[str, PaperSet]:
    """Every set of the shared folder, by folder name (sorted)."""
    if not PAPER_SETS.is_dir():
        pytest.fail(f"the paper's image sets are missing: {PAPER_SETS}")
    out = {}
    for path in sorted(p for p in PAPER_SETS.iterdir() if p.is_dir()):
        info = read_info(path)
        out[path.name] = PaperSet(
            path.name,
            path,
            load_image_set(path),
            float(info["x"]),
            float(info["y"]),
            float(info["yaw"]),
        )
    assert len(out) >= 11, f"expected the 11 shared sets, found {sorted(out)}"
    return out


@pytest.fixture(scope="session")
def recorded_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An autonomous run of ``paper`` at 64 px, recorded once for the session."""
    from tests.logs import record

    path = tmp_path_factory.mktemp("recorded") / "run.mcap"
    done = record(path)
    assert done.returncode == 0, done.stderr
    return path
