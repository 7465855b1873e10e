"""The production matcher: Algorithm 2 against every known junction, as a cascade.

It computes the normalized cross-correlation of :mod:`localizer.similarity` in two
stages (the arithmetic in :mod:`localizer.spectra`, each set made ready once by
:mod:`localizer.prepared`), both validated against the reference on the paper's own image sets
(``tests/localizer/test_fastmatch.py``, ``benchmarks/bench_localizer.py``):

1. **Screen** every known junction in one batch: images area-downsampled by
   ``coarse_downsample`` (columns) and ``coarse_row_downsample`` (rows), vertical
   shift searched within ``+-coarse_dy_px`` (default 0: at 1/16 scale the area
   averaging already blurs the vertical offsets the accurate stage searches for).
   For each vertical shift this is one complex matrix product over image rows for
   all image pairs of all junctions, one batched inverse FFT along the columns and
   a multiplication by precomputed inverse window norms. Cheap, biased, good
   enough to rank: it never decides (see :func:`localizer.localizer.best_candidate`).
2. **Refine** the ``refine_candidates`` best junctions: the best at its
   ``refine_offsets`` most promising cyclic offsets (all of them by default), the
   others (which only set the margin) at their ``runner_up_offsets`` best. Images
   are at the paper's quarter scale (``fine_downsample``,
   :func:`localizer.similarity.paper_scaled`: the very pixels the reference sees).
   The full "same" range of vertical and horizontal shifts is searched by 2-D FFT,
   so the peak value is the reference's up to float32 rounding; a parabola through
   the peak's neighbours gives a sub-pixel column shift (the reference reports whole
   pixels). Views of one junction from different entries differ by tens of pixels
   vertically (robot pitch and roll turn with the camera), so the accurate stage
   must not restrict the vertical search.

Junctions not refined keep their screening match (``SetMatch.refined`` is False).
Everything that depends on one image set alone is computed once, when the set is
prepared; the refinement's spectra are computed on demand for the few candidates.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from pipemap.errors import LocalizerError
from pipemap.localizer import transforms
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.index import INDEX_ABOVE, SHORTLIST, DescriptorIndex, descriptor
from pipemap.localizer.prepared import (
    FastConfig,
    PreparedSet,
    _zoomed_peaks,
    prepare,
)
from pipemap.localizer.similarity import SetMatch, best_offset, wrap_angle_rad
from pipemap.localizer.spectra import (
    FineSpectra,
    _fft_length,
    _fine_spectra,
    _offset_scores,
    _same_shifts,
)

__all__ = [
    "FastConfig",
    "FastMatcher",
    "FineSpectra",
    "PreparedSet",
    "prepare",
]


class FastMatcher:
    """A database of known image sets, matched against a query by the cascade.

    The database only grows: :meth:`add` appends a prepared set and returns its
    index. :meth:`match` returns one :class:`SetMatch` per known set, in order.
    """

    def __init__(self, config: FastConfig | None = None) -> None:
        self.config = config if config is not None else FastConfig()
        self._sets: list[PreparedSet] = []
        self._image_rows: np.ndarray | None = None  # (F, R, N*M), grown by add()
        self._inv_window_norm: np.ndarray | None = None  # (D, N*M, Wc)
        #: Refinement spectra of the last few refined known sets, rebuilt on demand.
        self._fine_cache: OrderedDict[int, PreparedSet] = OrderedDict()
        #: Descriptors of the known sets (:mod:`localizer.index`): above
        #: ``index_above`` known sets, only ``shortlist`` of them are screened.
        self._index = DescriptorIndex()
        self.index_above = INDEX_ABOVE
        self.shortlist = SHORTLIST
        #: The last set described and its descriptor: a new junction's sweep is
        #: described once, for the shortlist of its match and again for its add.
        self._described: tuple[PreparedSet, np.ndarray] | None = None
        # The transforms are loaded here, not at the first sweep (without scipy's
        # pocketfft, scipy.fft's import would make a robot's first decision wait 0.2 s).
        transforms.backend()

    def __len__(self) -> int:
        return len(self._sets)

    def prepare(self, image_set: ImageSet) -> PreparedSet:
        """Prepare a set with this matcher's settings (a query, or one to add)."""
        return prepare(image_set, self.config)

    def _check(self, prepared: PreparedSet) -> None:
        if not prepared.screenable:
            raise LocalizerError("a set prepared without its screening arrays cannot be screened")
        if self._sets:
            _check_alike(self._sets[0], prepared)

    def add(self, prepared: PreparedSet, keep_spectra: bool = False) -> int:
        """Append a prepared set to the database; returns its index.

        The screening arrays grow by doubling, so adding M sets copies O(M) data.
        With ``keep_spectra``, a set given with its searched refinement spectra keeps
        them (a caller that holds them anyway, as :func:`pairwise_matches` does);
        otherwise they are rebuilt from the compact images when refined.
        """
        self._check(prepared)
        n = prepared.count
        used = len(self._sets) * n
        if self._image_rows is None or self._inv_window_norm is None:
            self._image_rows = np.empty_like(
                prepared.image_rows, shape=(*prepared.image_rows.shape[:2], 4 * n)
            )
            self._inv_window_norm = np.empty_like(
                prepared.inv_window_norm,
                shape=(prepared.inv_window_norm.shape[0], 4 * n, prepared.inv_window_norm.shape[2]),
            )
        elif used + n > self._image_rows.shape[2]:
            self._image_rows = _grown(self._image_rows, axis=2)
            self._inv_window_norm = _grown(self._inv_window_norm, axis=1)
        self._image_rows[:, :, used : used + n] = prepared.image_rows
        self._inv_window_norm[:, used : used + n, :] = prepared.inv_window_norm
        self._index.add(self._descriptor(prepared))
        self._sets.append(_kept(prepared, keep_spectra))
        return len(self._sets) - 1

    def kept_bytes(self) -> int:
        """Memory the database holds for its known sets (screening arrays as used,
        the compact refinement images, and any zoomed spectra)."""
        arrays = self._screening_arrays()
        total = self._index.nbytes() + (0 if arrays is None else sum(a.nbytes for a in arrays))
        for known in self._sets:
            if known.fine_images is not None:
                total += known.fine_images.values.nbytes
            total += sum(
                z.spectrum.nbytes + (0 if z.inv_window_norm is None else z.inv_window_norm.nbytes)
                for z in known.zoomed
            )
        return total

    def cache_bytes(self) -> int:
        """Memory the refinement cache holds beyond :meth:`kept_bytes`: the spectra of
        the last few refined known sets (at most ``_FINE_CACHE`` of them, whatever the
        size of the database)."""
        total = 0
        for i, cached in self._fine_cache.items():
            fine = cached.fine
            if fine is not None and self._sets[i].fine is None:  # rebuilt, not kept
                assert fine.inv_window_norm is not None
                total += fine.spectrum.nbytes + fine.inv_window_norm.nbytes + fine.inv_norm.nbytes
        return total

    def _descriptor(self, prepared: PreparedSet) -> np.ndarray:
        """The index's descriptor of ``prepared``, computed once for the set last
        described (0.3-0.5 ms a sweep at 400 px)."""
        described = self._described
        if described is not None and described[0] is prepared:
            return described[1]
        row = _descriptor_of(prepared)
        self._described = (prepared, row)
        return row

    def _refinable(self, i: int) -> PreparedSet:
        """Known set ``i`` with its refinement spectra, from a small cache (they cost
        ten times the compact images to keep, and a few ms to rebuild)."""
        cached = self._fine_cache.get(i)
        if cached is not None:
            self._fine_cache.move_to_end(i)
            return cached
        known = self._sets[i]
        if known.fine is None or known.fine.inv_window_norm is None:
            assert known.fine_images is not None
            known = replace(known, fine=_fine_spectra(known.fine_images.images(), known.width_px))
        self._fine_cache[i] = known
        if len(self._fine_cache) > _FINE_CACHE:
            self._fine_cache.popitem(last=False)
        return known

    def _screening_arrays(self) -> tuple[np.ndarray, np.ndarray] | None:
        if self._image_rows is None or self._inv_window_norm is None:
            return None
        used = len(self._sets) * self._sets[0].count
        return self._image_rows[:, :, :used], self._inv_window_norm[:, :used, :]

    def screen(
        self, query: PreparedSet, subset: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Screening peaks of every image pair against every known set (or the known
        sets of ``subset``, ascending indices).

        Returns peak NCC and peak column shift (full-resolution px), both of shape
        ``(M, N, N)``: entry ``[i, j, m]`` is image j of the query against image m of
        known set i (the i-th of ``subset``).
        """
        self._check(query)
        n = query.count
        arrays = self._screening_arrays()
        if arrays is None or (subset is not None and subset.size == 0):
            return np.empty((0, n, n)), np.empty((0, n, n))
        image_rows, inv_window_norm = arrays
        if subset is not None:
            columns = (subset[:, None] * n + np.arange(n)[None, :]).ravel()
            image_rows, inv_window_norm = image_rows[:, :, columns], inv_window_norm[:, columns]
        total = image_rows.shape[2]
        rows = query.template_rows.shape[2]
        wd = inv_window_norm.shape[2]
        length = _fft_length(wd)
        lags = _same_shifts(wd) % length
        n_dy = inv_window_norm.shape[0]
        best = np.full((n, total), -np.inf)
        best_col = np.zeros((n, total))
        for d in range(n_dy):
            dy = d - n_dy // 2
            r0, r1 = max(0, -dy), min(rows, rows - dy)
            spectrum = np.matmul(
                query.template_rows[:, :, r0:r1], image_rows[:, r0 + dy : r1 + dy, :]
            )  # (F, N, N*M): every query image against every known image
            corr = transforms.irfft(spectrum.transpose(1, 2, 0), n=length, axis=2)[:, :, lags]
            ncc = corr * inv_window_norm[d][None, :, :]
            ncc *= query.inv_template_norm[:, None, None].astype(np.float32)
            col = np.argmax(ncc, axis=2)  # whole pixels: the screen ranks, it does not measure
            value = np.take_along_axis(ncc, col[:, :, None], axis=2)[:, :, 0]
            better = value > best
            best = np.where(better, value, best)
            best_col = np.where(better, col, best_col)
        best = np.clip(best, -1.0, 1.0)
        dx_full = (best_col - wd // 2) * (query.width_px / wd)
        m_sets = total // n
        return (
            best.reshape(n, m_sets, n).transpose(1, 0, 2),
            dx_full.reshape(n, m_sets, n).transpose(1, 0, 2),
        )

    def match(
        self, query: PreparedSet, exclude: int | None = None, expected: Sequence[int] = ()
    ) -> list[SetMatch]:
        """Algorithm 2 between the query (as A) and every known set (as B).

        The known set ``exclude`` (if any) cannot be the answer: it is screened but
        never refined, so the refinement goes to the sets that can. Above
        ``index_above`` known sets only the ``shortlist`` nearest by descriptor and
        the ``expected`` ones are screened; the others get :data:`UNSCREENED`.
        """
        subset = None
        if len(self._sets) > self.index_above:
            subset = self._index.nearest(self._descriptor(query), self.shortlist, expected)
        peaks, shifts = self.screen(query, subset)
        if peaks.shape[0] == 0:
            return []
        ids = list(range(len(self._sets))) if subset is None else subset.tolist()
        scores = _offset_scores(peaks)  # (M, N), row r for known set ids[r]
        baselines = [(query.baseline + self._sets[i].baseline) / 2.0 for i in ids]
        # Rotations between the robots' headings, not between the sweeps' cameras.
        turns = [query.camera_angle_rad - self._sets[i].camera_angle_rad for i in ids]
        screened = _screened_matches(
            scores, shifts, query.fov_rad, query.width_px, baselines, turns
        )
        if subset is None:
            matches = screened
        else:
            matches = Shortlisted([UNSCREENED] * len(self._sets))
            matches.screened = ids
            for r, i in enumerate(ids):
                matches[i] = screened[r]
        row = {i: r for r, i in enumerate(ids)}
        order = sorted(
            (i for i in ids if i != exclude),
            key=lambda i: (-matches[i].similarity, i),
        )
        n = query.count
        n_offsets = min(self.config.refine_offsets, n)
        # The best candidate decides: refine its most promising offsets. The others
        # only set the margin: their best few offsets are enough.
        n_runner_up = min(self.config.runner_up_offsets, n)
        blocks = [
            (i, int(k))
            for rank, i in enumerate(order[: self.config.refine_candidates])
            for k in np.argsort(-scores[row[i]], kind="stable")[
                : n_offsets if rank == 0 else n_runner_up
            ]
        ]
        # Each candidate's spectra fetched once: with more candidates than the cache
        # holds, fetching them again for each block rebuilt them every time.
        refinable = {i: self._refinable(i) for i, _ in blocks}
        if blocks:
            values, columns = _zoomed_peaks(query, [(refinable[i], k) for i, k in blocks])
        j = np.arange(n)
        for i in order[: self.config.refine_candidates]:
            peak_ncc = np.full((n, n), -np.inf)
            peak_dx = np.zeros((n, n))
            for b, (owner, k) in enumerate(blocks):
                if owner == i:
                    fine = refinable[i].fine
                    assert fine is not None
                    peak_ncc[j, (j + k) % n] = values[b]
                    peak_dx[j, (j + k) % n] = columns[b] * (fine.full_width_px / fine.width)
            refined = best_offset(peak_ncc, peak_dx, query.fov_rad, query.width_px)
            matches[i] = replace(refined, similarity=refined.similarity - baselines[row[i]]).turned(
                turns[row[i]]
            )
        return matches


def _check_alike(known: PreparedSet, prepared: PreparedSet) -> None:
    if prepared.shape_key != known.shape_key:
        raise LocalizerError(
            f"image set {prepared.shape_key[:5]} (images, height, width, fov, kept "
            f"fraction) does not match the database's {known.shape_key[:5]}"
        )


def _descriptor_of(prepared: PreparedSet) -> np.ndarray:
    """The index's descriptor of a set, from its quarter-scale refinement images."""
    assert prepared.fine_images is not None  # every prepared set has them
    return descriptor(prepared.fine_images.images(), prepared.fov_rad)


#: The match of a known set the index left out of the screen: lower than any score.
UNSCREENED = SetMatch(
    similarity=-2.0,
    image_shift=0,
    pixel_shift=0.0,
    rotation_rad=0.0,
    rotation_pinhole_rad=0.0,
    refined=False,
)


class Shortlisted(list[SetMatch]):
    """Matches of a shortlisted screen; ``screened``: the sets not :data:`UNSCREENED`
    (ascending), so that no caller looks at every known set to find them."""

    screened: list[int]


#: Known sets whose refinement spectra a matcher keeps at hand.
_FINE_CACHE = 8


def _kept(prepared: PreparedSet, keep_spectra: bool = False) -> PreparedSet:
    """What a database keeps of a set: no query-side screening rows (the matcher's
    arrays hold its searched rows), no spectra when the compact images can rebuild them
    (unless ``keep_spectra`` and they are the searched ones)."""
    empty = np.zeros((0,), dtype=np.complex64)
    searched = prepared.fine is not None and prepared.fine.inv_window_norm is not None
    rebuildable = prepared.fine_images is not None and not (keep_spectra and searched)
    return replace(
        prepared,
        template_rows=empty,
        image_rows=empty,
        inv_window_norm=np.zeros((0,), dtype=np.float32),
        fine=None if rebuildable else prepared.fine,
        fine_images=None if prepared.fine_images is None else prepared.fine_images.packed(),
    )


def _screened_matches(
    scores: np.ndarray,
    shifts: np.ndarray,
    fov_rad: float,
    width_px: int,
    baselines: list[float] | None = None,
    turns: list[float] | None = None,
) -> list[SetMatch]:
    """Algorithm 2's choice for every screened junction at once (``refined=False``),
    less junction i's baseline ``baselines[i]`` and turned by ``turns[i]`` (see
    :meth:`SetMatch.turned`), if given.

    The same arithmetic as :func:`localizer.similarity.best_offset`, vectorized over
    the M junctions; one record each, built once (at a thousand junctions, building
    and replacing records cost more than the arithmetic).
    """
    m, n = scores.shape
    j = np.arange(n)
    best_k = np.argmax(scores, axis=1)  # first maximum: lowest offset on a tie
    cols = (j[None, :] + best_k[:, None]) % n  # (M, N): the pairs of each best offset
    pair_shifts = shifts[np.arange(m)[:, None], j[None, :], cols]
    mean_shift = pair_shifts.mean(axis=1)
    focal_px = (width_px / 2.0) / math.tan(fov_rad / 2.0)
    median_angle = np.median(2.0 * np.arctan(pair_shifts / (2.0 * focal_px)), axis=1)
    step = 2.0 * math.pi / n
    baselines = [0.0] * m if baselines is None else baselines
    turns = [0.0] * m if turns is None else turns
    out = []
    for i, k in enumerate(best_k.tolist()):
        rotation = wrap_angle_rad(k * step + mean_shift[i] * fov_rad / width_px)
        pinhole = wrap_angle_rad(k * step + median_angle[i])
        turn = turns[i]
        if turn != 0.0:  # as SetMatch.turned does
            rotation = wrap_angle_rad(rotation + turn)
            pinhole = wrap_angle_rad(pinhole + turn)
        out.append(
            SetMatch(
                similarity=float(scores[i, k]) - baselines[i],
                image_shift=k,
                pixel_shift=float(mean_shift[i]),
                rotation_rad=rotation,
                rotation_pinhole_rad=pinhole,
                refined=False,
            )
        )
    return out


def _grown(array: np.ndarray, axis: int) -> np.ndarray:
    """A copy of ``array`` with twice the room along ``axis``, the data at the start."""
    shape = list(array.shape)
    shape[axis] *= 2
    out = np.empty_like(array, shape=tuple(shape))
    index = [slice(None)] * array.ndim
    index[axis] = slice(0, array.shape[axis])
    out[tuple(index)] = array
    return out
