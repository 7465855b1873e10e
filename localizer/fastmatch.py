"""The production matcher: Algorithm 2 against every known junction, as a cascade.

It computes the normalized cross-correlation of :mod:`localizer.similarity` in two
stages, both validated against the reference on the paper's own image sets
(``tests/localizer/test_fastmatch.py``, ``benchmarks/bench_localizer.py``):

1. **Screen** every known junction in one batch: images area-downsampled by
   ``coarse_downsample``, vertical shift searched only within ``+-coarse_dy_px``.
   For each vertical shift this is one complex matrix product over image rows for
   all image pairs of all junctions, one batched inverse FFT along the columns and a
   division by precomputed window norms. Cheap, biased, good enough to rank.
2. **Refine** the ``refine_candidates`` best junctions at their ``refine_offsets``
   best cyclic offsets: images decimated by ``fine_downsample`` (plain subsampling:
   area averaging removes uncorrelated pixel noise and raised NCC by about 0.02 on the
   paper's images, subsampling keeps the reference's statistics), full "same" range of
   vertical and horizontal shifts by 2-D FFT, and a parabola through the peak's
   neighbours for a sub-pixel column shift. Views of one junction from different
   entries differ by tens of pixels vertically (robot pitch and roll turn with the
   camera), so the accurate stage must not restrict the vertical search.

Junctions not refined keep their screening match (``SetMatch.refined`` is False).
Everything that depends on one image set alone is computed once, when the set is
prepared; the refinement's spectra are computed on demand for the few candidates.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import cv2
import numpy as np

from localizer.imageset import ImageSet
from localizer.similarity import SetMatch, best_offset, sums_from_integral
from pipemap.errors import LocalizerError

__all__ = ["FastConfig", "FastMatcher", "FineSpectra", "PreparedSet", "pairwise_matches", "prepare"]


@dataclass(frozen=True)
class FastConfig:
    """Settings of the cascade (see the module docstring)."""

    coarse_downsample: int = 16
    coarse_dy_px: int = 16
    fine_downsample: int = 4
    refine_candidates: int = 2
    refine_offsets: int = 2

    def __post_init__(self) -> None:
        for name in ("coarse_downsample", "fine_downsample", "refine_candidates", "refine_offsets"):
            if getattr(self, name) < 1:
                raise LocalizerError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.coarse_dy_px < 0:
            raise LocalizerError(f"coarse_dy_px must be >= 0, got {self.coarse_dy_px}")


@dataclass(frozen=True, eq=False)
class PreparedSet:
    """What the fast path keeps of one image set; built by :func:`prepare`."""

    count: int
    width_px: int
    fov_rad: float
    shape_key: tuple[float, ...]
    #: Screening: conj(rfft) of each zero-mean template row, (F, N, R) complex64.
    template_rows: np.ndarray
    #: Screening: 1 / sqrt(sum T^2) of each template, (N,).
    inv_template_norm: np.ndarray
    #: Screening: rfft of each zero-mean searched row, (F, R, N) complex64.
    image_rows: np.ndarray
    #: Screening: 1 / sqrt(local variance sum) of each searched image per (dy, dx),
    #: (D, N, Wc); 0 where the window is flat.
    inv_window_norm: np.ndarray
    #: Refinement: spectra and norms of the decimated images.
    fine: FineSpectra


def _area_downsampled(images: np.ndarray, factor: int) -> np.ndarray:
    if factor == 1:
        return images.astype(np.float64)
    n, h, w = images.shape
    hd, wd = max(h // factor, 2), max(w // factor, 2)
    out = np.empty((n, hd, wd), dtype=np.float64)
    for i in range(n):
        out[i] = cv2.resize(images[i], (wd, hd), interpolation=cv2.INTER_AREA)
    return out


def _decimated(images: np.ndarray, factor: int) -> np.ndarray:
    step = max(1, min(factor, images.shape[1] // 2, images.shape[2] // 2))
    return np.ascontiguousarray(images[:, ::step, ::step], dtype=np.float32)


def _fft_length(size: int) -> int:
    # Shifts -S/2 .. S/2-1 must not wrap around: at least 1.5 S, then a fast size.
    return int(cv2.getOptimalDFTSize(size + (size + 1) // 2))


def _same_shifts(size: int) -> np.ndarray:
    return np.arange(size) - size // 2


def prepare(image_set: ImageSet, config: FastConfig) -> PreparedSet:
    """Precompute everything the fast path needs of one image set."""
    cropped = image_set.cropped()
    small = _area_downsampled(cropped, config.coarse_downsample)
    n, rows, wd = small.shape
    zero_mean = small - small.mean(axis=(1, 2), keepdims=True)
    spectra = np.fft.rfft(zero_mean.astype(np.float32), n=_fft_length(wd), axis=2)  # (N, R, F)
    dy_max = min(config.coarse_dy_px // config.coarse_downsample, rows - 1)
    dys = np.arange(-dy_max, dy_max + 1)
    inv_norms = _inverse(_window_norms(zero_mean, dys, _same_shifts(wd))).transpose(1, 0, 2)
    return PreparedSet(
        count=n,
        width_px=image_set.width,
        fov_rad=image_set.fov_rad,
        shape_key=(
            *image_set.images.shape,
            image_set.fov_rad,
            image_set.keep_top_fraction,
            *(getattr(config, f) for f in _SHAPE_FIELDS),
        ),
        template_rows=np.ascontiguousarray(np.conj(spectra).transpose(2, 0, 1), np.complex64),
        inv_template_norm=_inverse(np.sqrt(np.sum(zero_mean**2, axis=(1, 2)))),
        image_rows=np.ascontiguousarray(spectra.transpose(2, 1, 0), np.complex64),
        inv_window_norm=np.ascontiguousarray(inv_norms, dtype=np.float32),
        fine=_fine_spectra(_decimated(cropped, config.fine_downsample), image_set.width),
    )


_SHAPE_FIELDS = ("coarse_downsample", "coarse_dy_px", "fine_downsample")


def _subpixel(left: np.ndarray, centre: np.ndarray, right: np.ndarray) -> np.ndarray:
    """Offset in [-0.5, 0.5] of the vertex of the parabola through three samples."""
    curvature = left - 2.0 * centre + right
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = 0.5 * (left - right) / curvature
    return np.where((curvature < 0) & np.isfinite(offset), np.clip(offset, -0.5, 0.5), 0.0)


def _peaks_along_columns(ncc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Peak value and sub-pixel column index over the last axis of an NCC array."""
    width = ncc.shape[-1]
    ix = np.argmax(ncc, axis=-1)

    def take(at: np.ndarray) -> np.ndarray:
        return np.take_along_axis(ncc, at[..., None], axis=-1)[..., 0]

    value = take(ix)
    left = take(np.maximum(ix - 1, 0))
    right = take(np.minimum(ix + 1, width - 1))
    interior = (ix > 0) & (ix < width - 1)
    return value, ix + np.where(interior, _subpixel(left, value, right), 0.0)


@dataclass(frozen=True, eq=False)
class FineSpectra:
    """Refinement data of one set: one spectrum serves both roles (template, searched)."""

    rows: int
    width: int
    full_width_px: int
    length: tuple[int, int]
    #: rfft2 of each zero-mean decimated image, (N, Ly, Fx) complex64.
    spectrum: np.ndarray
    #: 1 / sqrt(sum T^2) of each image, (N,).
    inv_norm: np.ndarray
    #: 1 / sqrt(local variance sum) over the "same" shift range, (N, R, W) float32;
    #: 0 where the window is flat.
    inv_window_norm: np.ndarray
    #: Phase ramp that moves shift (-R/2, -W/2) to index (0, 0) of the correlation.
    ramp: np.ndarray


def _window_norms(zero_mean: np.ndarray, dys: np.ndarray, dxs: np.ndarray) -> np.ndarray:
    """sqrt(S2 - S1^2/n) of each image's windows at the given shifts, (N, D, X)."""
    n, rows, width = zero_mean.shape
    sums = np.empty((2, n, rows + 1, width + 1))
    for i in range(n):
        sums[0, i], sums[1, i] = cv2.integral2(zero_mean[i], sdepth=cv2.CV_64F, sqdepth=cv2.CV_64F)
    s1, s2 = sums_from_integral(sums, dys, dxs)
    norms: np.ndarray = np.sqrt(np.maximum(s2 - s1 * s1 / (rows * width), 0.0))
    return norms


def _inverse(norms: np.ndarray) -> np.ndarray:
    """1 / norms, with 0 where a norm is rounding noise next to the largest of its image.

    Axis 0 indexes images (a 1-D array is one value per image, compared across all).
    Flat windows then score NCC 0, as in the reference, instead of dividing by ~0.
    """
    if norms.ndim == 1:
        largest = np.full(norms.shape, norms.max(initial=0.0))
    else:
        largest = norms.reshape(len(norms), -1).max(axis=1, initial=0.0)
        largest = largest.reshape((-1,) + (1,) * (norms.ndim - 1))
    out: np.ndarray = np.zeros_like(norms)
    np.divide(1.0, norms, out=out, where=norms > 1e-9 * np.maximum(largest, 1e-300))
    return out


def _fine_spectra(fine: np.ndarray, full_width_px: int) -> FineSpectra:
    n, rows, width = fine.shape
    zero_mean = fine.astype(np.float64) - fine.mean(axis=(1, 2), keepdims=True)
    length = (_fft_length(rows), _fft_length(width))
    spectrum = np.fft.rfft2(zero_mean.astype(np.float32), s=length)
    norms = _window_norms(zero_mean, _same_shifts(rows), _same_shifts(width))
    fy = np.fft.fftfreq(length[0])[:, None]
    fx = np.fft.rfftfreq(length[1])[None, :]
    ramp = np.exp(-2j * np.pi * (fy * (rows // 2) + fx * (width // 2))).astype(np.complex64)
    return FineSpectra(
        rows=rows,
        width=width,
        full_width_px=full_width_px,
        length=length,
        spectrum=spectrum,
        inv_norm=_inverse(np.sqrt(np.sum(zero_mean**2, axis=(1, 2)))),
        inv_window_norm=_inverse(norms).astype(np.float32),
        ramp=ramp,
    )


def _fine_peaks(
    query: FineSpectra, known: FineSpectra, pairs: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Peak NCC and sub-pixel column shift (decimated px) of image pairs ``(j, m)``.

    ``corr[dy, dx] = sum T[y, x] B[y + dy, x + dx]`` is ``irfft2(conj(FT) * FB)``; the
    ramp moves the "same" range of shifts to the start of the output.
    """
    rows, width = known.rows, known.width
    product = np.conj(query.spectrum[pairs[:, 0]]) * known.spectrum[pairs[:, 1]]
    product *= known.ramp
    ncc = (
        np.fft.irfft2(product, s=known.length)[:, :rows, :width]
        * known.inv_window_norm[pairs[:, 1]]
    )
    ncc *= query.inv_norm[pairs[:, 0], None, None].astype(np.float32)
    best_row = np.argmax(ncc.reshape(len(pairs), -1), axis=1) // width
    row_values = ncc[np.arange(len(pairs)), best_row]  # (P, W): the peak's row
    value, column = _peaks_along_columns(row_values)
    return np.clip(value, -1.0, 1.0), column - width // 2


def _offset_scores(peaks: np.ndarray) -> np.ndarray:
    """Mean peak NCC per cyclic offset: ``[..., k] = mean_j peaks[..., j, (j+k) % N]``."""
    n = peaks.shape[-1]
    j = np.arange(n)
    cols = (j[None, :] + j[:, None]) % n  # row k holds (j + k) mod N
    scores: np.ndarray = peaks[..., j[None, :], cols].mean(axis=-1)
    return scores


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

    def __len__(self) -> int:
        return len(self._sets)

    def prepare(self, image_set: ImageSet) -> PreparedSet:
        """Prepare a set with this matcher's settings (a query, or one to add)."""
        return prepare(image_set, self.config)

    def _check(self, prepared: PreparedSet) -> None:
        if self._sets and prepared.shape_key != self._sets[0].shape_key:
            raise LocalizerError(
                f"image set {prepared.shape_key[:5]} (images, height, width, fov, kept "
                f"fraction) does not match the database's {self._sets[0].shape_key[:5]}"
            )

    def add(self, prepared: PreparedSet) -> int:
        """Append a prepared set to the database; returns its index.

        The screening arrays grow by doubling, so adding M sets copies O(M) data.
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
        self._sets.append(prepared)
        return len(self._sets) - 1

    def _screening_arrays(self) -> tuple[np.ndarray, np.ndarray] | None:
        if self._image_rows is None or self._inv_window_norm is None:
            return None
        used = len(self._sets) * self._sets[0].count
        return self._image_rows[:, :, :used], self._inv_window_norm[:, :used, :]

    def screen(self, query: PreparedSet) -> tuple[np.ndarray, np.ndarray]:
        """Screening peaks of every image pair against every known set.

        Returns peak NCC and peak column shift (full-resolution px), both of shape
        ``(M, N, N)``: entry ``[i, j, m]`` is image j of the query against image m of
        known set i.
        """
        self._check(query)
        n = query.count
        arrays = self._screening_arrays()
        if arrays is None:
            return np.empty((0, n, n)), np.empty((0, n, n))
        image_rows, inv_window_norm = arrays
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
            corr = np.fft.irfft(spectrum.transpose(1, 2, 0), n=length, axis=2)[:, :, lags]
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

    def _refine(self, query: PreparedSet, index: int, offsets: np.ndarray) -> SetMatch:
        known = self._sets[index].fine
        n = query.count
        j = np.arange(n)
        pairs = np.array([(jj, (jj + k) % n) for k in offsets for jj in j])
        value, column = _fine_peaks(query.fine, known, pairs)
        peak_ncc = np.full((n, n), -np.inf)
        peak_dx = np.zeros((n, n))
        peak_ncc[pairs[:, 0], pairs[:, 1]] = value
        peak_dx[pairs[:, 0], pairs[:, 1]] = column * (known.full_width_px / known.width)
        return best_offset(peak_ncc, peak_dx, query.fov_rad, query.width_px)

    def match(self, query: PreparedSet) -> list[SetMatch]:
        """Algorithm 2 between the query (as A) and every known set (as B)."""
        peaks, shifts = self.screen(query)
        matches = [
            replace(best_offset(peaks[i], shifts[i], query.fov_rad, query.width_px), refined=False)
            for i in range(peaks.shape[0])
        ]
        if not matches:
            return matches
        scores = _offset_scores(peaks)  # (M, N)
        order = sorted(range(len(matches)), key=lambda i: (-matches[i].similarity, i))
        n_offsets = min(self.config.refine_offsets, query.count)
        for i in order[: self.config.refine_candidates]:
            offsets = np.argsort(-scores[i], kind="stable")[:n_offsets]
            matches[i] = self._refine(query, i, offsets)
        return matches


def _grown(array: np.ndarray, axis: int) -> np.ndarray:
    """A copy of ``array`` with twice the room along ``axis``, the data at the start."""
    shape = list(array.shape)
    shape[axis] *= 2
    out = np.empty_like(array, shape=tuple(shape))
    index = [slice(None)] * array.ndim
    index[axis] = slice(0, array.shape[axis])
    out[tuple(index)] = array
    return out


def pairwise_matches(
    sets: list[ImageSet], config: FastConfig | None = None, every_offset: bool = False
) -> dict[tuple[int, int], SetMatch]:
    """Algorithm 2 for every unordered pair ``(i, j)``, ``i < j``, set i as A.

    Each set is prepared once and every pair is refined, at the offsets a localizer
    decision would refine (``config.refine_offsets``), or at every cyclic offset
    with ``every_offset`` (slower; it only matters between different junctions,
    where all offsets score alike).
    """
    base = config if config is not None else FastConfig()
    prepared = [prepare(s, base) for s in sets]
    out: dict[tuple[int, int], SetMatch] = {}
    if not sets:
        return out
    offsets = sets[0].count if every_offset else base.refine_offsets
    everything = replace(base, refine_candidates=len(sets), refine_offsets=offsets)
    for i in range(len(sets) - 1):
        later = FastMatcher(everything)
        for p in prepared[i + 1 :]:
            later.add(p)
        for offset, match in enumerate(later.match(prepared[i])):
            out[(i, i + 1 + offset)] = match
    return out
