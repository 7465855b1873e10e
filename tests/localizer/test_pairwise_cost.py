"""What every pair of ``pipemap match`` costs: each set's refinement spectra built once,
the refinement's temporaries bounded, and the very same numbers whatever the grouping."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer import (
    FastConfig,
    FastMatcher,
    fastmatch,
    pairwise,
    pairwise_matches,
    spectra,
    transforms,
)
from pipemap.localizer import prepared as prepared_module
from pipemap.localizer.fastmatch import prepare
from pipemap.localizer.pairwise import for_pairs
from tests.localizer.synthetic import panorama, sweep


def _sets(count: int) -> list[Any]:
    return [sweep(panorama(seed)) for seed in range(count)]


def _counting(monkeypatch: pytest.MonkeyPatch, module: Any, name: str) -> list[int]:
    calls: list[int] = []
    real = getattr(module, name)

    def counted(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, counted)
    return calls


def test_each_sets_searched_spectra_are_built_once(monkeypatch: pytest.MonkeyPatch) -> None:
    sets = [for_pairs(prepare(s, FastConfig())) for s in _sets(6)]
    built = _counting(monkeypatch, pairwise, "_fine_spectra")
    matches = pairwise_matches(sets)
    assert len(matches) == 15
    # Sets 1..5 once as searched sets (set 1..4 then serve as queries too), set 0 once
    # as a query: rebuilt for every pair, it was 15 and more.
    assert len(built) == 6


def test_a_match_fetches_each_candidates_spectra_once(monkeypatch: pytest.MonkeyPatch) -> None:
    # More candidates than the matcher's cache holds: fetching them again per block
    # rebuilt every one a second time.
    count = fastmatch._FINE_CACHE + 3
    config = FastConfig(refine_candidates=count, runner_up_offsets=6)
    matcher = FastMatcher(config)
    sets = _sets(count + 1)
    for s in sets[1:]:
        matcher.add(matcher.prepare(s))
    query = matcher.prepare(sets[0])
    built = _counting(monkeypatch, fastmatch, "_fine_spectra")
    matcher.match(query)
    assert len(built) == count


def test_refinement_runs_in_bounded_groups_with_the_same_numbers(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    sets = _sets(5)
    whole = pairwise_matches(sets, every_offset=True)
    groups: list[int] = []
    real = spectra._chunk_rows

    def spy(query: Any, ramped: np.ndarray, blocks: list[Any], *work: Any) -> np.ndarray:
        groups.append(len(blocks))
        return real(query, ramped, blocks, *work)

    monkeypatch.setattr(spectra, "_chunk_rows", spy)
    monkeypatch.setattr(spectra, "PEAK_CHUNK_BYTES", 1)  # one block at a time
    one_by_one = pairwise_matches(sets, every_offset=True)
    assert groups and max(groups) == 1
    assert one_by_one == whole  # every field, to the last bit
    groups.clear()
    monkeypatch.setattr(spectra, "PEAK_CHUNK_BYTES", 1 << 40)
    assert pairwise_matches(sets, every_offset=True) == whole
    assert max(groups) > 1


def test_every_group_of_a_call_is_transformed_in_the_same_work_arrays(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    sets = [pairwise._searched(prepare(s, FastConfig())) for s in _sets(3)]
    fine = [s.fine for s in sets]
    blocks = [(known, k) for known in fine[1:] for k in range(sets[0].count)]
    whole = spectra._fine_peaks(fine[0], blocks)
    arrays: list[int] = []  # the address of the work arrays each group is given
    real = spectra._chunk_rows

    def spy(query: Any, ramped: np.ndarray, chunk: list[Any], work: Any) -> np.ndarray:
        arrays.append(work.spectra.__array_interface__["data"][0])
        arrays.append(work.ncc.__array_interface__["data"][0])
        return real(query, ramped, chunk, work)

    monkeypatch.setattr(spectra, "_chunk_rows", spy)
    monkeypatch.setattr(spectra, "PEAK_CHUNK_BYTES", 5 * fine[0].spectrum.nbytes)
    grouped = spectra._fine_peaks(fine[0], blocks)
    assert len(arrays) == 2 * 3  # 12 blocks in groups of 5, 5 and 2
    assert len(set(arrays[0::2])) == 1 and len(set(arrays[1::2])) == 1
    # The last, shorter group reads none of the group before it.
    assert all(np.array_equal(g, w) for g, w in zip(grouped, whole, strict=True))


@pytest.mark.parametrize("zooms", [(), (1.15,)])
def test_every_offset_of_every_pair_skips_the_screen_with_the_matchers_numbers(
    monkeypatch: pytest.MonkeyPatch, zooms: tuple[float, ...]
) -> None:
    """At the defaults every offset of every pair is refined, so pairwise_matches
    neither screens nor ranks; its matches are a FastMatcher's to the last bit."""
    config = FastConfig(zooms=zooms)
    sets = [pairwise._searched(prepare(s, config)) for s in _sets(5)]
    everything = FastConfig(zooms=zooms, refine_candidates=4, runner_up_offsets=6)
    matcher = FastMatcher(everything)
    for known in sets[1:]:
        matcher.add(known, keep_spectra=True)
    by_matcher = matcher.match(sets[0])
    screens = _counting(monkeypatch, FastMatcher, "screen")
    found = pairwise_matches(sets[:1] + sets[1:], config)
    assert screens == []
    assert [found[(0, j)] for j in range(1, 5)] == by_matcher  # every field, every bit
    # With fewer offsets than images the screen chooses them, as in a decision.
    pairwise_matches(sets, FastConfig(zooms=zooms, refine_offsets=2))
    assert len(screens) == 4


def test_sets_prepared_for_pairs_build_their_refinement_spectra_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """prepare(refinement=False) leaves out the spectra for_pairs would drop, so each
    set's are built once, by whoever refines it, with the same numbers."""
    from pipemap.localizer import prepared as prepared_module

    images = _sets(4)
    whole = pairwise_matches([prepare(s, FastConfig()) for s in images])
    lean = [prepare(s, FastConfig(), refinement=False) for s in images]
    assert all(p.fine is None for p in lean)
    assert prepare(images[0], FastConfig(baseline=True), refinement=False).fine is not None
    built = _counting(monkeypatch, prepared_module, "_fine_spectra")
    built_later = _counting(monkeypatch, pairwise, "_fine_spectra")
    assert pairwise_matches(images) == whole
    assert len(built) == 0 and len(built_later) == 4


def test_sets_whose_every_offset_is_refined_are_prepared_without_screening_arrays(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    images = _sets(4)
    screened = _counting(monkeypatch, prepared_module, "_screening")
    at_defaults = pairwise_matches(images)
    assert screened == []  # every offset of every pair: nothing is screened
    cheap = FastConfig(refine_offsets=2)
    with_matcher = pairwise_matches(images, cheap)
    assert len(screened) == len(images)  # a FastMatcher screens: the sets need them
    # The same numbers as sets prepared with their screening arrays.
    full = [for_pairs(prepare(s, FastConfig(), refinement=False)) for s in images]
    assert full[0].screenable
    assert pairwise_matches(full) == at_defaults
    assert pairwise_matches(images, cheap) == with_matcher
    bare = pairwise.prepare_for_pairs(images[0], FastConfig())
    assert not bare.screenable and bare.template_rows.size == 0
    assert pairwise.prepare_for_pairs(images[0], cheap).screenable
    assert not pairwise.prepare_for_pairs(images[0], cheap, every_offset=True).screenable
    # Such a set cannot go where it would be screened.
    with pytest.raises(LocalizerError, match="screening arrays"):
        FastMatcher(FastConfig()).add(bare)
    with pytest.raises(LocalizerError, match="screening arrays"):
        pairwise_matches([bare, bare], cheap)


def test_each_pairs_peak_is_read_off_its_whole_scaled_ncc_bit_for_bit() -> None:
    """The refinement scales only the row it keeps; the peaks are those of the whole
    NCC array scaled, pair by pair, to the last bit (a flat image's too)."""
    rng = np.random.default_rng(5)
    images = rng.uniform(0, 255, (2, 6, 24, 40))
    images[:, 2] = 7.0  # flat: its 1 / norm and window norms are 0
    query, known = (spectra._fine_spectra(i, 160) for i in images)
    blocks = [(known, k) for k in range(6)]
    values, columns = spectra._fine_peaks(query, blocks)
    ramped = np.conj(query.spectrum) * spectra._ramp(query.length, query.rows, query.width)
    assert known.inv_window_norm is not None and query.inv_norm[2] == 0.0
    for b, (_, k) in enumerate(blocks):
        for j in range(6):
            m = (j + k) % 6
            along_y = transforms.ifft(ramped[j] * known.spectrum[m], axis=0)[: query.rows]
            ncc = transforms.irfft(along_y, n=query.length[1], axis=1)[:, : query.width]
            ncc = ncc * known.inv_window_norm[m]  # (y, x)
            ncc *= np.float32(query.inv_norm[j])
            y, x = np.unravel_index(int(np.argmax(ncc)), ncc.shape)
            value, column = spectra._peaks_along_columns(ncc[y])
            assert values[b, j] == np.clip(value, -1.0, 1.0)
            assert columns[b, j] == column - query.width // 2
