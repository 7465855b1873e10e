"""The descriptor index that shortlists the screen above ``INDEX_ABOVE`` junctions."""

from __future__ import annotations

import numpy as np
import pytest

from pipemap.localizer import FastMatcher, fastmatch
from pipemap.localizer.fastmatch import UNSCREENED, Shortlisted
from pipemap.localizer.index import DescriptorIndex, descriptor
from tests.localizer.synthetic import panorama, sweep


def _descriptor(seed: int, turn: int = 0) -> np.ndarray:
    s = sweep(panorama(seed), turn=turn)
    return descriptor(s.images, s.fov_rad)


def test_a_turned_sweep_stays_nearer_its_junction_than_any_other() -> None:
    home = _descriptor(1)
    others = [float(_descriptor(seed) @ home) for seed in range(2, 8)]
    for turn in (240, 480, 17, 60, 500):  # whole images, then turns within an image
        turned = float(_descriptor(1, turn) @ home)
        assert turned > max(others) + 0.4, (turn, turned, others)
    assert float(_descriptor(1, 240) @ home) == pytest.approx(1.0, abs=1e-5)


def test_a_mirrored_sweep_is_not_its_junction() -> None:
    s = sweep(panorama(1))
    mirrored = descriptor(s.images[::-1, :, ::-1].copy(), s.fov_rad)
    assert float(mirrored @ _descriptor(1)) < 0.5


def test_nearest_takes_the_k_best_ties_to_the_earliest_and_the_expected() -> None:
    index = DescriptorIndex()
    rows = np.eye(4, dtype=np.float32)
    for r in (rows[0], rows[1], rows[1], rows[2], rows[3], rows[1]):
        index.add(r)
    query = rows[1]
    assert index.nearest(query, 2).tolist() == [1, 2]
    assert index.nearest(query, 2, also=[4, 99]).tolist() == [1, 2, 4]
    assert index.nearest(query, 10).tolist() == [0, 1, 2, 3, 4, 5]
    index.truncate(2)
    assert index.nearest(query, 1).tolist() == [1]


def test_the_index_grows_past_its_first_rows() -> None:
    index = DescriptorIndex()
    for k in range(40):
        row = np.zeros(40, dtype=np.float32)
        row[k] = 1.0
        index.add(row)
    assert len(index) == 40 and index.nbytes() == 40 * 40 * 4
    assert index.nearest(np.eye(40, dtype=np.float32)[33], 1).tolist() == [33]


def _matcher(seeds: list[int], above: int, shortlist: int) -> FastMatcher:
    matcher = FastMatcher()
    matcher.index_above, matcher.shortlist = above, shortlist
    for seed in seeds:
        matcher.add(matcher.prepare(sweep(panorama(seed))))
    return matcher


def test_above_the_limit_only_the_shortlist_and_the_expected_are_screened() -> None:
    seeds = list(range(10, 16))
    matcher = _matcher(seeds, above=3, shortlist=2)
    query = matcher.prepare(sweep(panorama(12), turn=30))
    matches = matcher.match(query, expected=[5])
    screened = [i for i, m in enumerate(matches) if m is not UNSCREENED]
    assert 2 in screened and 5 in screened and len(screened) == 3
    # The list names them, so the decision finds them without a pass over every set.
    assert isinstance(matches, Shortlisted) and matches.screened == screened
    assert max(range(len(matches)), key=lambda i: matches[i].similarity) == 2
    assert matches[2].refined


def test_at_or_under_the_limit_every_junction_is_screened_as_before() -> None:
    seeds = list(range(10, 16))
    exhaustive = _matcher(seeds, above=6, shortlist=1)
    query = exhaustive.prepare(sweep(panorama(12), turn=30))
    full = exhaustive.match(query)
    assert UNSCREENED not in full
    everything = _matcher(seeds, above=0, shortlist=6).match(query)
    assert full == everything


def test_a_new_junction_is_described_once_for_its_match_and_its_add(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    matcher = _matcher(list(range(10, 14)), above=2, shortlist=2)
    query = matcher.prepare(sweep(panorama(20), turn=30))
    other = matcher.prepare(sweep(panorama(21)))
    described: list[int] = []
    real = fastmatch.descriptor

    def counted(images: np.ndarray, fov_rad: float) -> np.ndarray:
        described.append(len(images))
        return real(images, fov_rad)

    monkeypatch.setattr(fastmatch, "descriptor", counted)
    matcher.match(query)
    matcher.add(query)
    assert len(described) == 1
    # What the index keeps is the descriptor of that set, not of the last one described.
    matcher.match(other)
    matcher.add(query)
    assert len(described) == 3
    rows = matcher._index._rows
    assert rows is not None
    expected = real(query.fine_images.images(), query.fov_rad)  # type: ignore[union-attr]
    assert np.array_equal(rows[4], expected) and np.array_equal(rows[5], expected)
