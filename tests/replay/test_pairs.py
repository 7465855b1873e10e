"""The score's pairs of visits (the paper's Table 1 two ways): every pair of one
junction, and the pairs of different junctions up to a budget, an even seeded sample
beyond it, so that scoring a thousand-junction log does not compare two million."""

from __future__ import annotations

import dataclasses
import weakref
from collections.abc import Iterator, Mapping
from pathlib import Path

import numpy as np
import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer import FastConfig, ImageSet, pairwise_matches
from pipemap.replay import FileSource, replay, sweeps_of
from pipemap.replay.score import pair_statistics, true_sweeps

LOG = Path(__file__).resolve().parents[2] / "recordings" / "random8_loops.mcap"


@pytest.fixture(scope="module")
def replayed():  # type: ignore[no-untyped-def]
    source = FileSource(LOG)
    return replay(source), true_sweeps(source)


def test_pairs_asked_for_are_the_pairs_of_all(replayed) -> None:  # type: ignore[no-untyped-def]
    result, _ = replayed
    sets = [result.visit_sets[i] for i in sorted(result.visit_sets)][:6]
    every = pairwise_matches(sets)
    some = pairwise_matches(sets, pairs=[(4, 5), (0, 3), (0, 1)])
    assert sorted(some) == [(0, 1), (0, 3), (4, 5)]
    assert all(some[p] == every[p] for p in some)
    with pytest.raises(LocalizerError, match="pair"):
        pairwise_matches(sets, pairs=[(3, 2)])


def test_under_the_budget_every_pair_is_compared(replayed) -> None:  # type: ignore[no-untyped-def]
    result, truths = replayed
    stats = pair_statistics(result, truths)
    visits = len(result.visit_sets)
    assert len(stats.same) + len(stats.different) == visits * (visits - 1) // 2
    assert "of" not in stats.document()["different"]


def test_over_the_budget_the_different_pairs_are_a_seeded_sample(replayed) -> None:  # type: ignore[no-untyped-def]
    result, truths = replayed
    every = pair_statistics(result, truths)
    budget = 10
    sample = pair_statistics(result, truths, max_different=budget)
    assert sample.same == every.same  # every pair of one junction, always
    assert sample.rotation_errors_rad == every.rotation_errors_rad
    assert len(sample.different) == budget < len(every.different)
    assert set(sample.different) <= set(every.different)
    assert pair_statistics(result, truths, max_different=budget) == sample
    doc = sample.document()["different"]
    assert doc["n"] == budget and doc["of"] == len(every.different)


def test_the_score_text_says_a_sample_is_one() -> None:
    from pipemap.cli.replay_commands import _stat

    assert _stat({"mean": 0.3, "std": 0.04, "n": 61}) == "0.300 +- 0.040 (n=61)"
    assert _stat({"mean": 0.3, "std": 0.04, "n": 5000, "of": 20909}) == (
        "0.300 +- 0.040 (n=5000 of 20909)"
    )


class _Watched(Mapping[int, ImageSet]):
    """A replay's visit sets, counting how many of those handed out are alive at once."""

    def __init__(self, sets: Mapping[int, ImageSet]) -> None:
        self._sets = sets
        self.alive = self.most_alive = 0

    def _gone(self) -> None:
        self.alive -= 1

    def __getitem__(self, sweep_id: int) -> ImageSet:
        image_set = self._sets[sweep_id]
        self.alive += 1
        self.most_alive = max(self.most_alive, self.alive)
        weakref.finalize(image_set, self._gone)
        return image_set

    def __iter__(self) -> Iterator[int]:
        return iter(self._sets)

    def __len__(self) -> int:
        return len(self._sets)


def test_the_pairs_hold_no_more_than_a_set_at_a_time(replayed) -> None:  # type: ignore[no-untyped-def]
    # A thousand-junction log has thousands of visit sets, 3.8 MB each at 400 px as
    # float32: the replay keeps each sweep's 8-bit frames and makes its set on each
    # lookup, and the pairs prepare one set at a time from it.
    # (Compared from the sets, as pairs with other matcher settings are.)
    result, truths = replayed
    sweep = next(iter(result.visit_sets))
    assert result.visit_sets[sweep] is not result.visit_sets[sweep]
    watched = _Watched(result.visit_sets)
    from_sets = dataclasses.replace(result, visit_sets=watched, visit_prepared={})
    stats = pair_statistics(from_sets, truths)
    assert stats == pair_statistics(dataclasses.replace(result, visit_prepared={}), truths)
    assert len(watched) > 10 and watched.most_alive == 1


def test_the_pairs_compare_the_sets_as_the_replay_prepared_them(replayed) -> None:  # type: ignore[no-untyped-def]
    """A score keeps each visit as the localizer's matcher prepared it, without its
    refinement spectra, not its sweep: the very pair statistics of preparing every
    visit's sweep anew, for about a tenth of the memory."""
    result, truths = replayed
    assert sorted(result.visit_prepared) == sorted(result.visit_sets)
    anew = pair_statistics(dataclasses.replace(result, visit_prepared={}), truths)
    assert pair_statistics(dataclasses.replace(result, visit_sets={}), truths) == anew
    for sweep_id, kept in result.visit_prepared.items():
        assert kept.fine is None and kept.fine_images is not None
        frames = result.visit_sets[sweep_id].images.size  # the sweep's bytes in 8 bits
        held = sum(a.nbytes for a in (kept.template_rows, kept.image_rows, kept.inv_window_norm))
        assert held + kept.fine_images.values.nbytes < frames / 4


def test_pairs_with_other_matcher_settings_need_the_sets(replayed) -> None:  # type: ignore[no-untyped-def]
    result, truths = replayed
    other = FastConfig(refine_offsets=3)
    with_sets = pair_statistics(result, truths, other)
    assert with_sets == pair_statistics(
        dataclasses.replace(result, visit_prepared={}), truths, other
    )
    with pytest.raises(ValueError, match="other matcher settings"):
        pair_statistics(dataclasses.replace(result, visit_sets={}), truths, other)
    kept = [result.visit_prepared[i] for i in sorted(result.visit_prepared)][:3]
    with pytest.raises(LocalizerError, match="other matcher settings"):
        pairwise_matches(kept, FastConfig(coarse_downsample=8))


def test_a_replay_keeps_each_sweep_in_8_bits() -> None:
    sweeps = sweeps_of(FileSource(LOG).robot_messages()).sweeps
    assert {s.frames.dtype for s in sweeps} == {np.dtype(np.uint8)}
    first = sweeps[0]
    assert not first.frames.flags.writeable
    images = first.images
    assert images.images.dtype == np.float32
    assert np.array_equal(images.images, first.frames)
    assert (images.count, images.camera_angle_rad) == (first.count, first.camera_angle_rad)


def test_a_replay_keeps_the_prepared_sets_only_when_asked() -> None:
    """``pipemap replay`` holds the map, not the visits: it asks for neither the sweeps
    nor the prepared sets; ``score`` asks for the prepared sets alone."""
    bare = replay(FileSource(LOG), keep_sets=False, keep_prepared=False)
    assert bare.visit_prepared == {} and len(bare.visit_sets) == 0
    for_score = replay(FileSource(LOG), keep_sets=False)
    assert len(for_score.visit_prepared) == len(for_score.visits) > 10
    assert len(for_score.visit_sets) == 0
