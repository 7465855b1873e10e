"""Algorithm 2 for every pair of a list of image sets: what ``pipemap match`` computes.

Each set is prepared once (:mod:`localizer.prepared`) and its refinement spectra
built once; at the default settings every cyclic offset of every pair is refined
(:func:`localizer.spectra._fine_peaks`), or, with ``screen``, every offset that a
screen on images about :data:`SCREEN_WIDTH` px wide finds within
:data:`SCREEN_MARGIN` of the best (:func:`_promising`). With fewer offsets asked for, a
:class:`localizer.fastmatch.FastMatcher` chooses them as a localizer decision would.
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
from pipemap.localizer.similarity import (
    SetMatch,
    pinhole_rotation_rad,
    relative_rotation_rad,
)
from pipemap.localizer.spectra import FineSpectra, _fine_peaks, _fine_spectra

__all__ = ["SCREEN_MARGIN", "for_pairs", "pairwise_matches", "prepare_for_pairs"]

#: With ``screen``, :func:`pairwise_matches` refines each offset whose screened mean
#: NCC is within this of the pair's best offset's. On the paper's 25 sets (300 pairs),
#: screened on images 50 px wide, the offset that wins at the paper's scale was never
#: more than 0.0118 below the best screened one at 800 px, 0.0067 at 400 px.
SCREEN_MARGIN = 0.035

#: The screen's images are the refinement's reduced by a whole factor to about this
#: width (at least by 2): 200 px at 800 px by 4, 100 px at 400 px by 2. Refinement
#: images narrower than twice this, or fewer than :data:`SCREEN_MIN_ROWS` rows once
#: reduced, have every offset refined.
SCREEN_WIDTH = 48
SCREEN_MIN_ROWS = 8


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


def prepare_for_pairs(
    image_set: ImageSet, config: FastConfig, every_offset: bool = False
) -> PreparedSet:
    """``image_set`` prepared as :func:`pairwise_matches` with the same ``config`` and
    ``every_offset`` needs it: without refinement spectra (:func:`for_pairs`), and
    without the screening arrays where every offset of every pair will be refined (at
    the defaults), which never screens."""
    return for_pairs(
        prepare(
            image_set,
            config,
            refinement=False,
            screening=not _refines_every_offset(config, image_set.count, every_offset),
        )
    )


def _refines_every_offset(config: FastConfig, count: int, every_offset: bool) -> bool:
    """Whether :func:`pairwise_matches` refines every offset of every pair of sets of
    ``count`` images (then it needs no :class:`FastMatcher`)."""
    return every_offset or config.refine_offsets >= count


def _prepared_for(
    item: ImageSet | PreparedSet, config: FastConfig, every_offset: bool
) -> PreparedSet:
    if isinstance(item, ImageSet):
        return prepare_for_pairs(item, config, every_offset)
    # Its shape key: the images' shape, field of view and kept fraction, then settings.
    if item.shape_key[5:] != config_key(config):
        raise LocalizerError("a set prepared with other matcher settings than the pairs'")
    return for_pairs(item)


def pairwise_matches(
    sets: Sequence[ImageSet | PreparedSet],
    config: FastConfig | None = None,
    every_offset: bool = False,
    pairs: list[tuple[int, int]] | None = None,
    screen: bool = False,
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

    ``screen`` (ignored with ``every_offset``, zooms, or images too small, see
    :data:`SCREEN_WIDTH`): where every offset would be refined, refine only those a
    screen on images about :data:`SCREEN_WIDTH` px wide puts within
    :data:`SCREEN_MARGIN` of the best (:func:`_promising`). A pair's similarity is then
    the reference's when its best offset is among them, and below it otherwise; on the
    paper's 300 pairs, at 800 and 400 px, it always was.
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
    screens: dict[int, FineSpectra | None] = {}  # the screen's spectra of each set
    offsets = sets[0].count if every_offset else base.refine_offsets
    screen = screen and not every_offset and not base.zooms
    for i, later in later_of.items():
        everything = replace(
            base, refine_candidates=len(later), refine_offsets=offsets, runner_up_offsets=offsets
        )
        for k in (i, *later):
            if k not in prepared:
                prepared[k] = _prepared_for(sets[k], base, every_offset)
        for j in later:
            if j not in searched:
                searched[j] = _searched(prepared[j])
        # A set searched before has the very spectrum a query's would be.
        query = searched[i] if i in searched else _as_query(prepared[i])
        if offsets >= query.count:  # every offset of every pair: the screen would rank only
            chosen = None
            if screen:
                for k in (i, *later):
                    if k not in screens:
                        screens[k] = _screen_spectra(searched.get(k, query))
                chosen = _promising(screens[i], [screens[j] for j in later])
            found = _every_offset(query, [searched[j] for j in later], chosen)
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
            screens.pop(k, None)
    return out


def _screen_spectra(prepared: PreparedSet) -> FineSpectra | None:
    """Searched spectra of ``prepared``'s refinement images reduced to about
    :data:`SCREEN_WIDTH` px wide (box means of ``f x f`` pixels, ``f >= 2``), for the
    screen of :func:`_promising`; None when they are too small for that or the set has
    fewer than three images."""
    assert prepared.fine_images is not None
    images = prepared.fine_images.images()
    n, rows, width = images.shape
    f = width // SCREEN_WIDTH
    if n < 3 or f < 2 or rows // f < SCREEN_MIN_ROWS:
        return None
    whole = images[:, : rows - rows % f, : width - width % f]
    reduced = whole.reshape(n, rows // f, f, width // f, f).mean(axis=(2, 4))
    return _fine_spectra(reduced, prepared.width_px)


def _promising(
    query: FineSpectra | None, known: list[FineSpectra | None]
) -> list[np.ndarray] | None:
    """The offsets of each pair worth refining: every offset whose mean peak NCC on
    the screen's images (the paper's Algorithm 2 on :func:`_screen_spectra`, a
    sixteenth of the transforms at 800 px) is within :data:`SCREEN_MARGIN` of the
    pair's best; None (every offset) if a set has no screen spectra."""
    if query is None or any(other is None for other in known):
        return None
    n = len(query.spectrum)
    blocks = [(other, k) for other in known if other is not None for k in range(n)]
    values, _ = _fine_peaks(query, blocks)
    means = values.reshape(len(known), n, n).mean(axis=2)  # (pair, offset)
    best = means.max(axis=1, keepdims=True)
    return [np.flatnonzero(row) for row in means >= best - SCREEN_MARGIN]


def _best_refined(
    values: np.ndarray, dx: np.ndarray, offsets: np.ndarray, query: PreparedSet
) -> SetMatch:
    """:func:`localizer.similarity.best_offset` of a pair refined at ``offsets`` only
    (ascending; the others score -inf there and never win): ``values[i, j]`` and
    ``dx[i, j]`` (full-resolution px) are the peak of query image j at offset
    ``offsets[i]``. The same arithmetic on the same values, so the same bits, without
    building the pair's N x N arrays (a tenth of ``match``'s time a pair at 400 px)."""
    n = query.count
    sims = values.astype(np.float64).mean(axis=1)
    shifts = dx.mean(axis=1)
    best = int(np.argmax(sims))  # the first maximum: the lowest offset on a tie
    k = int(offsets[best])
    shift = float(shifts[best])
    fov, width = query.fov_rad, query.width_px
    return SetMatch(
        similarity=float(sims[best]),
        image_shift=k,
        pixel_shift=shift,
        rotation_rad=relative_rotation_rad(k, shift, n, fov, width),
        rotation_pinhole_rad=pinhole_rotation_rad(k, dx[best], n, fov, width),
    )


def _every_offset(
    query: PreparedSet, known: list[PreparedSet], chosen: list[np.ndarray] | None = None
) -> list[SetMatch]:
    """:meth:`FastMatcher.match` of ``query`` against each of ``known`` (with their
    searched spectra) when every candidate is refined at every cyclic offset (or at
    the offsets ``chosen`` for each): the same blocks of image pairs, so the same
    numbers (each pair's peak is its own, whatever blocks it is computed with),
    without screening, ranking or a database (for 25 sets at 800 px, 0.5 s of
    ``pipemap match``'s CPU went to those). Offsets not chosen score -inf."""
    for other in known:
        _check_alike(query, other)
    n = query.count
    if not known:
        return []
    if chosen is None:
        chosen = [np.arange(n)] * len(known)
    blocks = [(other, int(k)) for other, ks in zip(known, chosen, strict=True) for k in ks]
    values, columns = _zoomed_peaks(query, blocks)
    out = []
    row = 0
    for other, ks in zip(known, chosen, strict=True):
        fine = other.fine
        assert fine is not None
        dx = columns[row : row + len(ks)] * (fine.full_width_px / fine.width)
        refined = _best_refined(values[row : row + len(ks)], dx, ks, query)
        row += len(ks)
        baseline = (query.baseline + other.baseline) / 2.0
        turn = query.camera_angle_rad - other.camera_angle_rad
        out.append(replace(refined, similarity=refined.similarity - baseline).turned(turn))
    return out
