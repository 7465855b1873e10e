"""Algorithm 2 for every pair of a list of image sets: what ``pipemap match`` computes.

Each set is prepared once (:mod:`localizer.prepared`) and its refinement spectra
built once; at the default settings every cyclic offset of every pair is refined
(:func:`localizer.spectra._fine_peaks`), with nothing to screen or rank. With fewer
offsets asked for, a :class:`localizer.fastmatch.FastMatcher` chooses them as a
localizer decision would.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from pipemap.errors import LocalizerError
from pipemap.localizer.fastmatch import FastMatcher, _check_alike
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.prepared import (
    FastConfig,
    PreparedSet,
    _zoomed_peaks,
    config_key,
    prepare,
)
from pipemap.localizer.similarity import SetMatch, best_offset
from pipemap.localizer.spectra import _fine_spectra

__all__ = ["for_pairs", "pairwise_matches"]


def for_pairs(prepared: PreparedSet) -> PreparedSet:
    """What a set keeps to be compared later, as either side of a pair: all but its
    refinement spectra, which its compact images give back exactly (at 400 px, 83 KiB
    of the 350 a prepared set holds, and of the 938 of the 8-bit sweep)."""
    return prepared if prepared.fine_images is None else replace(prepared, fine=None)


def _as_query(prepared: PreparedSet) -> PreparedSet:
    """``prepared`` with the refinement spectra a query needs (rebuilt if dropped)."""
    if prepared.fine is not None:
        return prepared
    assert prepared.fine_images is not None
    fine = _fine_spectra(prepared.fine_images.images(), prepared.width_px, searched=False)
    return replace(prepared, fine=fine)


def _searched(prepared: PreparedSet) -> PreparedSet:
    """``prepared`` with the refinement spectra a known set is searched by.

    :func:`pairwise_matches` builds them once per set and keeps them while the set has
    pairs to come (at 800 px, 1.6 MiB a set): rebuilt for every pair instead, as a
    matcher's cache of a few would, they took a quarter of ``pipemap match``'s time.
    """
    if prepared.fine is not None and prepared.fine.inv_window_norm is not None:
        return prepared
    assert prepared.fine_images is not None
    fine = _fine_spectra(prepared.fine_images.images(), prepared.width_px)
    return replace(prepared, fine=fine)


def _prepared_for(item: ImageSet | PreparedSet, config: FastConfig) -> PreparedSet:
    if isinstance(item, ImageSet):
        return for_pairs(prepare(item, config, refinement=False))
    # Its shape key: the images' shape, field of view and kept fraction, then settings.
    if item.shape_key[5:] != config_key(config):
        raise LocalizerError("a set prepared with other matcher settings than the pairs'")
    return for_pairs(item)


def pairwise_matches(
    sets: Sequence[ImageSet | PreparedSet],
    config: FastConfig | None = None,
    every_offset: bool = False,
    pairs: list[tuple[int, int]] | None = None,
) -> dict[tuple[int, int], SetMatch]:
    """Algorithm 2 for every unordered pair ``(i, j)``, ``i < j``, set i as A, or for
    the ``pairs`` given only (each ``i < j``).

    Each set is prepared once (only those in a pair; a set given prepared, with
    ``config``, is used as it is) and every pair is refined, at the offsets a
    localizer decision would refine (``config.refine_offsets``), or at every cyclic
    offset with ``every_offset`` (slower; it only matters between different
    junctions, where all offsets score alike). A pair's match does not depend on
    which other pairs are asked for. Sets wait for their last pair as
    :func:`for_pairs` keeps them.
    """
    base = config if config is not None else FastConfig()
    out: dict[tuple[int, int], SetMatch] = {}
    if not sets:
        return out
    if pairs is None:
        pairs = [(i, j) for i in range(len(sets)) for j in range(i + 1, len(sets))]
    later_of: dict[int, list[int]] = {}
    last_use: dict[int, int] = {}  # a set is prepared when first needed, dropped after
    for i, j in sorted(set(pairs)):
        if not 0 <= i < j < len(sets):
            raise LocalizerError(f"pair {(i, j)} is not two sets i < j of {len(sets)}")
        later_of.setdefault(i, []).append(j)
        last_use[i] = last_use[j] = i
    prepared: dict[int, PreparedSet] = {}
    searched: dict[int, PreparedSet] = {}  # with the spectra a known set is refined by
    offsets = sets[0].count if every_offset else base.refine_offsets
    for i, later in later_of.items():
        everything = replace(
            base, refine_candidates=len(later), refine_offsets=offsets, runner_up_offsets=offsets
        )
        for k in (i, *later):
            if k not in prepared:
                prepared[k] = _prepared_for(sets[k], base)
        for j in later:
            if j not in searched:
                searched[j] = _searched(prepared[j])
        # A set searched before has the very spectrum a query's would be.
        query = searched[i] if i in searched else _as_query(prepared[i])
        if offsets >= query.count:  # every offset of every pair: the screen would rank only
            found = _every_offset(query, [searched[j] for j in later])
        else:
            matcher = FastMatcher(everything)
            for j in later:
                matcher.add(searched[j], keep_spectra=True)
            found = matcher.match(query)
        for j, match in zip(later, found, strict=True):
            out[(i, j)] = match
        for k in [k for k in prepared if last_use[k] == i]:
            del prepared[k]
            searched.pop(k, None)
    return out


def _every_offset(query: PreparedSet, known: list[PreparedSet]) -> list[SetMatch]:
    """:meth:`FastMatcher.match` of ``query`` against each of ``known`` (with their
    searched spectra) when every candidate is refined at every cyclic offset: the
    same blocks of image pairs, so the same numbers (each pair's peak is its own,
    whatever blocks it is computed with), without screening, ranking or a database
    (for 25 sets at 800 px, 0.5 s of ``pipemap match``'s CPU went to those)."""
    for other in known:
        _check_alike(query, other)
    n = query.count
    if not known:
        return []
    values, columns = _zoomed_peaks(query, [(other, k) for other in known for k in range(n)])
    j = np.arange(n)
    out = []
    for r, other in enumerate(known):
        fine = other.fine
        assert fine is not None
        peak_ncc = np.full((n, n), -np.inf)
        peak_dx = np.zeros((n, n))
        for k in range(n):
            peak_ncc[j, (j + k) % n] = values[r * n + k]
            peak_dx[j, (j + k) % n] = columns[r * n + k] * (fine.full_width_px / fine.width)
        refined = best_offset(peak_ncc, peak_dx, query.fov_rad, query.width_px)
        baseline = (query.baseline + other.baseline) / 2.0
        turn = query.camera_angle_rad - other.camera_angle_rad
        out.append(replace(refined, similarity=refined.similarity - baseline).turned(turn))
    return out
