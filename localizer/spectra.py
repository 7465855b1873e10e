"""The normalized cross-correlation of image sets by FFT: what the matcher computes.

Window norms by integral images or separable cumulative sums, the refinement's
spectra of one set (:class:`FineSpectra`, computed once and usable as template or as
searched image), the peaks of blocks of image pairs at every "same" shift, and the
mean peak per cyclic offset. :mod:`localizer.fastmatch` puts them together.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

from pipemap.localizer import transforms
from pipemap.localizer.similarity import sums_from_integral

__all__ = ["FineSpectra"]


def _fft_length(size: int) -> int:
    # Shifts -S/2 .. S/2-1 must not wrap around: at least 1.5 S, then a fast size.
    return int(cv2.getOptimalDFTSize(size + (size + 1) // 2))


def _same_shifts(size: int) -> np.ndarray:
    return np.arange(size) - size // 2


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
    #: 0 where the window is flat. Only the searched set's are used: ``None`` for a
    #: query's (see :func:`_fine_spectra`).
    inv_window_norm: np.ndarray | None


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


def _same_range_sums(values: np.ndarray, axis: int) -> np.ndarray:
    """Window sums along ``axis`` for the "same" shifts ``-n/2 .. n/2 - 1``.

    The window at shift s covers ``[s, s + n)`` clipped to ``[0, n)``: a prefix of the
    axis for s < 0 and a suffix for s >= 0, so slices of one cumulative sum give
    every window without a gather.
    """
    n = values.shape[axis]
    half = n // 2

    def part(start: int, stop: int) -> tuple[slice, ...]:
        index = [slice(None)] * values.ndim
        index[axis] = slice(start, stop)
        return tuple(index)

    prefix = np.cumsum(values, axis=axis)
    out = np.empty_like(prefix)
    out[part(0, half)] = prefix[part(n - half - 1, n - 1)]  # s < 0: the first n + s
    total = prefix[part(n - 1, n)]
    out[part(half, half + 1)] = total  # s = 0: everything
    out[part(half + 1, n)] = total - prefix[part(0, n - half - 1)]  # s > 0: all but s
    return out


def _same_range_norms(zero_mean: np.ndarray) -> np.ndarray:
    """sqrt(S2 - S1^2/n) of every window of the "same" range, separably: (N, R, W)."""
    rows, width = zero_mean.shape[-2:]
    s1 = _same_range_sums(_same_range_sums(zero_mean, -1), -2)
    s2 = _same_range_sums(_same_range_sums(zero_mean * zero_mean, -1), -2)
    norms: np.ndarray = np.sqrt(np.maximum(s2 - s1 * s1 / (rows * width), 0.0))
    return norms


@functools.lru_cache(maxsize=8)
def _ramp(length: tuple[int, int], rows: int, width: int) -> np.ndarray:
    """Phase ramp that moves correlation shift (-R/2, -W/2) to output index (0, 0)."""
    fy = np.fft.fftfreq(length[0])[:, None]
    fx = np.fft.rfftfreq(length[1])[None, :]
    ramp = np.exp(-2j * np.pi * (fy * (rows // 2) + fx * (width // 2))).astype(np.complex64)
    ramp.setflags(write=False)
    return ramp


def _fine_spectra(fine: np.ndarray, full_width_px: int, searched: bool = True) -> FineSpectra:
    """The refinement data of quarter-scale images ``fine``; without ``searched``, as
    a query needs them (no window norms: a fifth of the time, never used for a query)."""
    n, rows, width = fine.shape
    zero_mean = fine.astype(np.float64) - fine.mean(axis=(1, 2), keepdims=True)
    length = (_fft_length(rows), _fft_length(width))
    # Two stages so that the zero rows of the padding are never transformed along x.
    along_x = transforms.rfft(zero_mean.astype(np.float32), n=length[1], axis=2)
    spectrum = transforms.fft(along_x, n=length[0], axis=1)
    return FineSpectra(
        rows=rows,
        width=width,
        full_width_px=full_width_px,
        length=length,
        spectrum=spectrum,
        inv_norm=_inverse(np.sqrt(np.sum(zero_mean**2, axis=(1, 2)))),
        inv_window_norm=(
            _inverse(_same_range_norms(zero_mean)).astype(np.float32) if searched else None
        ),
    )


def _fine_peaks(
    query: FineSpectra, blocks: list[tuple[FineSpectra, int]]
) -> tuple[np.ndarray, np.ndarray]:
    """Peak NCC and sub-pixel column shift (decimated px) of blocks of image pairs.

    A block ``(known, k)`` pairs image j of the query with image ``(j + k) mod N`` of
    ``known``; the result has one row of N values per block.
    ``corr[dy, dx] = sum T[y, x] B[y + dy, x + dx]`` is ``irfft2(conj(FT) * FB)``; a
    phase ramp moves the "same" range of shifts to the start of the output, so the
    inverse transform along x runs only on the rows that are kept.

    The blocks go through in groups of about :data:`PEAK_CHUNK_BYTES` of spectra: each
    image pair's transforms and peak are its own, so the values do not depend on the
    grouping, and the temporaries stay a few MiB (all at once, ``pipemap match`` on
    25 sets of 800 px held some 600 MiB of them). Every group is transformed in the
    same two work arrays (:class:`_Work`), allocated once per call.
    """
    n, width = len(query.spectrum), query.width
    ramped = np.conj(query.spectrum) * _ramp(query.length, query.rows, query.width)
    per_block = min(len(blocks), max(1, PEAK_CHUNK_BYTES // max(1, ramped.nbytes)))
    work = _Work.of(query, ramped, per_block)
    # Each image pair's row that holds its peak; the peaks are read off them at the end.
    peak_rows = np.empty((len(blocks) * n, width), dtype=np.float32)
    for start in range(0, len(blocks), per_block):
        chunk = blocks[start : start + per_block]
        peak_rows[start * n : (start + len(chunk)) * n] = _chunk_rows(query, ramped, chunk, work)
    value, column = _peaks_along_columns(peak_rows)
    shape = (len(blocks), n)
    return np.clip(value, -1.0, 1.0).reshape(shape), (column - width // 2).reshape(shape)


#: Bytes of pair spectra :func:`_fine_peaks` transforms at once (see there). With
#: the work arrays of :class:`_Work`, 2 MiB was quickest: 15.3 ms (the least of 15
#: runs, interleaved) for 60 blocks at 400 px against 17.9 with 4 MiB and 17.4 with
#: 1/4 MiB; at 800 px 55.3 against 56.4.
PEAK_CHUNK_BYTES = 2 << 20


@dataclass(frozen=True, eq=False)
class _Work:
    """The arrays a group of blocks is transformed in, reused by every group of a call.

    Fresh arrays of this size for every group (3 and 2 MiB at 800 px) came from the
    system each time, their pages faulted in and zeroed by the kernel: that took more
    CPU than the transforms themselves (measured on the paper's 800 px sets, 0.9 s of
    system time in 1.8 s for the refinement of 55 pairs).
    """

    #: The pair spectra, transformed along y in place: (blocks * N, Ly, Fx) complex64.
    spectra: np.ndarray
    #: The correlation rows kept, transformed along x: (blocks * N, R, Lx) float32.
    ncc: np.ndarray

    @classmethod
    def of(cls, query: FineSpectra, ramped: np.ndarray, blocks: int) -> _Work:
        n = len(ramped)
        return cls(
            spectra=np.empty((blocks * n, *ramped.shape[1:]), dtype=ramped.dtype),
            ncc=np.empty((blocks * n, query.rows, query.length[1]), dtype=np.float32),
        )


def _chunk_rows(
    query: FineSpectra,
    ramped: np.ndarray,
    blocks: list[tuple[FineSpectra, int]],
    work: _Work | None = None,
) -> np.ndarray:
    """The NCC row holding each image pair's peak, for a few blocks of
    :func:`_fine_peaks`, with the query's ramped spectrum: ``(blocks * N, width)``;
    transformed in ``work`` (arrays for at least these blocks) if given."""
    n, rows, width = len(query.spectrum), query.rows, query.width
    if work is None:
        work = _Work.of(query, ramped, len(blocks))
    used = len(blocks) * n
    product = work.spectra[:used].reshape(len(blocks), *ramped.shape)
    for b, (known, k) in enumerate(blocks):
        # Query image j with known image (j + k) mod N, in two slices (no gathered copy).
        np.multiply(ramped[: n - k], known.spectrum[k:], out=product[b, : n - k])
        np.multiply(ramped[n - k :], known.spectrum[:k], out=product[b, n - k :])
    along_y = transforms.ifft(work.spectra[:used], axis=1, out=work.spectra[:used])[:, :rows]
    ncc = transforms.irfft(along_y, n=query.length[1], axis=2, out=work.ncc[:used])
    ncc = ncc[:, :, :width]
    for b, (known, k) in enumerate(blocks):
        assert known.inv_window_norm is not None, "a query's spectra cannot be searched"
        ncc[b * n : b * n + n - k] *= known.inv_window_norm[k:]
        ncc[b * n + n - k : (b + 1) * n] *= known.inv_window_norm[:k]
    # Each pair's NCC is this times the query image's 1 / norm, a scale >= 0: rounding
    # keeps the order, so the scaled maximum of a row is its maximum scaled, and only
    # the row kept needs scaling (one pass over the array less, the same bits).
    scale = np.tile(query.inv_norm, len(blocks)).astype(np.float32)[:, None]
    # The first row holding the image's maximum: where a flat argmax would find it,
    # without copying the strided array to flatten it.
    best_row = np.argmax(ncc.max(axis=2) * scale, axis=1)
    rows_out: np.ndarray = ncc[np.arange(len(ncc)), best_row] * scale
    return rows_out


def _offset_scores(peaks: np.ndarray) -> np.ndarray:
    """Mean peak NCC per cyclic offset: ``[..., k] = mean_j peaks[..., j, (j+k) % N]``."""
    n = peaks.shape[-1]
    j = np.arange(n)
    cols = (j[None, :] + j[:, None]) % n  # row k holds (j + k) mod N
    scores: np.ndarray = peaks[..., j[None, :], cols].mean(axis=-1)
    return scores
