"""``pairwise_matches``'s screen: only the offsets a pass on small images finds promising are
refined, and on the paper's own sets the result is the exhaustive one, bit for bit."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from pipemap import api
from pipemap.localizer import FastConfig, pairwise, pairwise_matches
from pipemap.localizer.fastmatch import prepare
from pipemap.localizer.pairwise import for_pairs
from tests.conftest import PaperSet
from tests.localizer.synthetic import panorama, sweep


def _blocks_refined(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """The number of image-pair blocks each call of the refinement compares."""
    counts: list[int] = []
    real = pairwise._zoomed_peaks

    def counted(query: Any, blocks: list[Any]) -> Any:
        counts.append(len(blocks))
        return real(query, blocks)

    monkeypatch.setattr(pairwise, "_zoomed_peaks", counted)
    return counts


def test_screened_matches_are_the_exhaustive_ones_on_the_paper_sets(
    paper_sets: dict[str, PaperSet], monkeypatch: pytest.MonkeyPatch
) -> None:
    names = sorted(paper_sets)
    sets = [for_pairs(prepare(paper_sets[n].images, FastConfig())) for n in names]
    every = pairwise_matches(sets, every_offset=True)
    refined = _blocks_refined(monkeypatch)
    screened = pairwise_matches(sets, screen=True)
    assert screened == every  # similarity, offset, shift and rotations, exactly
    n = sets[0].count
    # The screen refines a fraction of the offsets, not all of them (55 pairs x 6).
    assert sum(refined) < 0.7 * len(every) * n


def test_the_screen_refines_the_offsets_near_the_best(monkeypatch: pytest.MonkeyPatch) -> None:
    # One junction, the second sweep turned by two images and a bit: one offset stands out.
    views = [sweep(panorama(1), width=400), sweep(panorama(1), turn=500, width=400)]
    sets = [for_pairs(prepare(view, FastConfig())) for view in views]
    halves = [pairwise._screen_spectra(pairwise._searched(s)) for s in sets]
    assert halves[0] is not None and halves[1] is not None
    chosen = pairwise._promising(halves[0], [halves[1]])
    assert chosen is not None
    values, _ = pairwise._fine_peaks(halves[0], [(halves[1], k) for k in range(sets[0].count)])
    means = values.mean(axis=1)
    expected = np.flatnonzero(means >= means.max() - pairwise.SCREEN_MARGIN)
    assert list(chosen[0]) == list(expected)
    assert list(chosen[0]) == [int(np.argmax(means))]  # 0.75 against 0.15 and below
    monkeypatch.setattr(pairwise, "SCREEN_MARGIN", 2.0)  # every offset is within 2
    assert len(pairwise._promising(halves[0], [halves[1]])[0]) == sets[0].count  # type: ignore[index]


def test_sets_too_small_for_the_screen_refine_every_offset(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    sets = [for_pairs(prepare(sweep(panorama(seed), width=160), FastConfig())) for seed in (1, 2)]
    assert pairwise._screen_spectra(pairwise._searched(sets[0])) is None
    refined = _blocks_refined(monkeypatch)
    assert pairwise_matches(sets, screen=True) == pairwise_matches(sets, every_offset=True)
    assert refined == [sets[0].count, sets[0].count]


def test_match_screens_unless_every_offset_is_asked_for(
    tmp_path: Any, paper_sets: dict[str, PaperSet], monkeypatch: pytest.MonkeyPatch
) -> None:
    folders = [paper_sets[n].path for n in sorted(paper_sets)[:3]]
    screens: list[int] = []
    real = pairwise._promising

    def counted(*args: Any) -> Any:
        screens.append(1)
        return real(*args)

    monkeypatch.setattr(pairwise, "_promising", counted)
    screened = api.match_image_sets(folders)
    assert screens
    screens.clear()
    assert api.match_image_sets(folders, every_offset=True) == screened
    assert not screens
