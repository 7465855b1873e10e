"""The view's trajectory (:class:`replay.view_topics.Trail`), read back from a real
rerun recording: at every time the path so far, unbroken, in pieces whose data grows
with the path's length, not with its square."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pipemap.replay import view_topics
from pipemap.replay.view_topics import TRAIL_ENTITY, Trail
from tests.replay.test_view import read_chunks

PIECE = 10


def _helix(points: int) -> tuple[np.ndarray, np.ndarray]:
    """Poses 1 cm apart along a helix, and their times (ns)."""
    t = np.arange(points) * 0.01
    xyz = np.stack([np.cos(t), np.sin(t), 0.05 * t], axis=1)
    return np.arange(points, dtype=np.int64) * 1_000_000, xyz


def _strips(path: Path) -> dict[str, list[tuple[int, np.ndarray]]]:
    """Every logged strip of each trail piece, with its time, in time order."""
    out: dict[str, list[tuple[int, np.ndarray]]] = {}
    for entity, chunks in read_chunks(path).items():
        if not entity.startswith(f"/{TRAIL_ENTITY}/"):
            continue
        rows: list[tuple[int, np.ndarray]] = []
        for chunk in chunks:
            batch = chunk.to_record_batch()
            if chunk.is_static or "LineStrips3D:strips" not in batch.schema.names:
                continue
            times = batch.column("sim_time").cast("int64").to_pylist()
            for t, strips in zip(
                times, batch.column("LineStrips3D:strips").to_pylist(), strict=True
            ):
                rows.append((t, np.array(strips[0])))
        out[entity] = sorted(rows, key=lambda r: r[0])
    return out


@pytest.fixture
def logged(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Trail, np.ndarray, Path]:
    """A 3 m helix logged in two calls (as the live view does) with pieces of 10."""
    import rerun as rr

    monkeypatch.setattr(view_topics, "TRAIL_PIECE_POINTS", PIECE)
    path = tmp_path / "trail.rrd"
    rec = rr.RecordingStream("pipemap_trail_test")
    rec.save(path)
    times, xyz = _helix(300)
    trail = Trail()
    trail.log(rec, times[:137], xyz[:137])
    trail.log(rec, times[137:], xyz[137:])
    rec.flush()
    rec.disconnect()
    return trail, times, path


def test_the_pieces_show_the_path_so_far_at_every_time(
    logged: tuple[Trail, np.ndarray, Path],
) -> None:
    trail, times, path = logged
    kept = np.array(trail.kept)
    assert len(kept) > 5 * PIECE
    strips = _strips(path)
    assert len(strips) == -(-(len(kept) - 1) // PIECE)  # pieces of 10 segments each
    logged_times = sorted({t for rows in strips.values() for t, _ in rows})
    for now in logged_times:
        # What the viewer shows at ``now``: each piece's latest strip (latest-at).
        shown = [
            [s for t, s in rows if t <= now][-1] for rows in strips.values() if rows[0][0] <= now
        ]
        joined = np.concatenate([shown[0], *(s[1:] for s in shown[1:])])
        for before, after in zip(shown[:-1], shown[1:], strict=True):
            assert np.array_equal(before[-1], after[0])  # unbroken
        assert np.allclose(joined, kept[: len(joined)])
        assert len(joined) == 1 + logged_times.index(now) + 1  # every point so far


def test_the_data_grows_with_the_path_not_its_square(
    logged: tuple[Trail, np.ndarray, Path],
) -> None:
    trail, _, path = logged
    points = sum(len(s) for rows in _strips(path).values() for _, s in rows)
    n = len(trail.kept)
    assert points <= (n - 1) * (PIECE + 1)
    assert points < n * n / 4  # one strip of the whole path each time: about n^2 / 2
