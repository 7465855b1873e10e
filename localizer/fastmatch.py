"""The production matcher: Algorithm 2 against every known junction, as a cascade.

It computes the normalized cross-correlation of :mod:`localizer.similarity` in two
stages, both validated against the reference on the paper's own image sets
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

import functools
import math
from collections import OrderedDict
from dataclasses import dataclass, replace

import cv2
import numpy as np

from pipemap.errors import LocalizerError
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.similarity import (
    SetMatch,
    best_offset,
    paper_scaled,
    sums_from_integral,
    wrap_angle_rad,
)

__all__ = ["FastConfig", "FastMatcher", "FineSpectra", "PreparedSet", "pairwise_matches", "prepare"]


@dataclass(frozen=True)
class FastConfig:
    """Settings of the cascade (see the module docstring)."""

    coarse_downsample: int = 16
    coarse_row_downsample: int = 16
    coarse_dy_px: int = 0
    #: The refinement's scale: the paper's quarter (see
    #: :func:`localizer.similarity.paper_scaled`).
    fine_downsample: int = 4
    refine_candidates: int = 2
    #: Offsets refined for the best junction: every one (up to 360) by default, so
    #: that its similarity is the reference's, which is cheap at the quarter scale.
    refine_offsets: int = 360
    runner_up_offsets: int = 1
    #: Zoom-in factors (> 1) also tried in the refinement, on either set of a pair;
    #: empty for the paper's algorithm. See :func:`_zoomed`.
    zooms: tuple[float, ...] = ()
    #: Subtract from each image its Gaussian blur of sigma = this fraction of the
    #: image width, before anything else; 0 for the paper's algorithm. See
    #: :func:`_high_passed`.
    highpass_fraction: float = 0.0
    #: Refine at the paper's quarter scale (area averaging, the reference's pixels).
    #: False: plain decimation, columns by ``fine_downsample`` and rows by 6, the
    #: resampling pipemap's ``--robust`` similarity was tuned with before issue 17.
    paper_resampling: bool = True
    #: Report each pair's similarity above its baseline: the mean of the two sets'
    #: :attr:`PreparedSet.baseline`. See :func:`_baseline`.
    baseline: bool = False

    def __post_init__(self) -> None:
        for name in (
            "coarse_downsample",
            "coarse_row_downsample",
            "fine_downsample",
            "refine_candidates",
            "refine_offsets",
            "runner_up_offsets",
        ):
            if getattr(self, name) < 1:
                raise LocalizerError(f"{name} must be >= 1, got {getattr(self, name)}")
        if self.coarse_dy_px < 0:
            raise LocalizerError(f"coarse_dy_px must be >= 0, got {self.coarse_dy_px}")
        if not (0.0 <= self.highpass_fraction <= 1.0):
            raise LocalizerError(
                f"highpass_fraction must be in [0, 1], got {self.highpass_fraction}"
            )
        for zoom in self.zooms:
            if not (1.0 < zoom <= 2.0):
                raise LocalizerError(f"zoom factors must be in (1, 2], got {zoom}")


@dataclass(frozen=True, eq=False)
class Compact:
    """Images stored in as few bytes as give them back exactly.

    A quarter-scale pixel of 8-bit images is a mean of 16 integers: ``scale`` times it
    is an integer below 65536, kept as uint16 (2 bytes a pixel instead of 8). Other
    images (not integer-valued, or not an exact box mean) are kept as float64.
    """

    values: np.ndarray
    scale: float

    @classmethod
    def of(cls, images: np.ndarray, scale: float) -> Compact:
        """The compact form of ``images`` (float64), exact or not compacted at all."""
        scaled = images * scale
        rounded = np.rint(scaled)
        if (
            images.size
            and float(rounded.min()) >= 0.0
            and float(rounded.max()) < 65536.0
            and np.array_equal(scaled, rounded)
            and np.array_equal(rounded / scale, images)
        ):
            return cls(rounded.astype(np.uint16), scale)
        return cls(np.asarray(images, dtype=np.float64), 1.0)

    def images(self) -> np.ndarray:
        """The images, exactly as given to :meth:`of`."""
        if self.scale == 1.0:
            return np.asarray(self.values, dtype=np.float64)
        out: np.ndarray = self.values.astype(np.float64) / self.scale
        return out


@dataclass(frozen=True, eq=False)
class PreparedSet:
    """What the fast path keeps of one image set; built by :func:`prepare`."""

    count: int
    width_px: int
    fov_rad: float
    #: The set's camera angle at its first image (see :class:`ImageSet`).
    camera_angle_rad: float
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
    #: Refinement: spectra and norms of the quarter-scale images (``None`` once the
    #: set is in a :class:`FastMatcher`, which keeps ``fine_images`` instead).
    fine: FineSpectra | None
    #: Refinement: the quarter-scale images themselves, compactly (see :class:`Compact`).
    fine_images: Compact | None = None
    #: Refinement: the same of the images zoomed in by each of ``FastConfig.zooms``.
    zoomed: tuple[FineSpectra, ...] = ()
    #: How alike unrelated views of this imagery look (0.0 unless ``FastConfig.baseline``).
    baseline: float = 0.0


def _area_downsampled(images: np.ndarray, row_factor: int, col_factor: int) -> np.ndarray:
    if row_factor == col_factor == 1:
        return images.astype(np.float64)
    n, h, w = images.shape
    hd, wd = max(h // row_factor, 2), max(w // col_factor, 2)
    out = np.empty((n, hd, wd), dtype=np.float64)
    for i in range(n):
        out[i] = cv2.resize(images[i], (wd, hd), interpolation=cv2.INTER_AREA)
    return out


def _fine_scaled(images: np.ndarray, config: FastConfig) -> np.ndarray:
    """The refinement's images: the paper's quarter scale, or plain decimation."""
    if config.paper_resampling:
        scaled: np.ndarray = paper_scaled(images, config.fine_downsample)
        return scaled
    rows = max(1, min(6, images.shape[1] // 2))  # the old fine_row_downsample
    cols = max(1, min(config.fine_downsample, images.shape[2] // 2))
    decimated: np.ndarray = np.ascontiguousarray(images[:, ::rows, ::cols], dtype=np.float64)
    return decimated


def _high_passed(image_set: ImageSet, sigma_px: float) -> ImageSet:
    """The set with each image's Gaussian blur of ``sigma_px`` subtracted.

    Every junction of a dark pipe lit by a lamp at the camera shares the same slow
    fall of brightness from the lit near wall to the dark far pipe. It raises the
    NCC of different junctions alike and varies with how the run's textures came
    out; removing it leaves the junction's own features (stains, joints, openings).
    The blur runs over the whole image, so the kept part's lower edge is filtered
    with its true neighbours.
    """
    images = np.asarray(image_set.images, dtype=np.float32)
    h, w = images.shape[1:]
    # A blur this wide is smooth: computed on an image shrunk by up to sigma/4 and
    # enlarged again, it costs 5 ms for six 400x400 images at sigma 70 px instead of
    # some 90, and differs from the full-size blur by about a tenth of the image's
    # contrast at most (measured: 2.1 grey levels against a standard deviation of 16).
    factor = max(1, min(int(sigma_px // 4), h // 4, w // 4))
    blurred = np.empty_like(images)
    for i, image in enumerate(images):
        small = cv2.resize(image, (w // factor, h // factor), interpolation=cv2.INTER_AREA)
        small = cv2.GaussianBlur(small, (0, 0), sigma_px / factor)
        blurred[i] = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
    return replace(image_set, images=images - blurred)


def _zoomed(image_set: ImageSet, zoom: float) -> np.ndarray:
    """The kept part of each image as seen by a camera zoomed in by ``zoom``.

    Magnified about the image centre (the principal point), which is what moving a
    camera towards the pipe wall it faces does to that wall; the parallax of nearer
    and farther surfaces is not modelled. Bilinear, and the magnified view never
    needs pixels from outside the image.
    """
    images = image_set.images
    h, w = images.shape[1:]
    cx, cy = (w - 1) / 2.0, (h - 1) / 2.0
    warp = np.array([[zoom, 0.0, (1.0 - zoom) * cx], [0.0, zoom, (1.0 - zoom) * cy]])
    kept = image_set.kept_rows
    out = np.empty((len(images), kept, w), dtype=np.float32)
    for i, image in enumerate(images):
        out[i] = cv2.warpAffine(
            np.asarray(image, dtype=np.float32),
            warp,
            (w, h),
            flags=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )[:kept]
    return out


def _fft_length(size: int) -> int:
    # Shifts -S/2 .. S/2-1 must not wrap around: at least 1.5 S, then a fast size.
    return int(cv2.getOptimalDFTSize(size + (size + 1) // 2))


def _same_shifts(size: int) -> np.ndarray:
    return np.arange(size) - size // 2


def prepare(image_set: ImageSet, config: FastConfig) -> PreparedSet:
    """Precompute everything the fast path needs of one image set."""
    if config.highpass_fraction > 0.0:
        image_set = _high_passed(image_set, config.highpass_fraction * image_set.width)
    cropped = image_set.cropped()
    fine_images = _fine_scaled(cropped, config)
    small = _area_downsampled(cropped, config.coarse_row_downsample, config.coarse_downsample)
    n, rows, wd = small.shape
    zero_mean = small - small.mean(axis=(1, 2), keepdims=True)
    spectra = np.fft.rfft(zero_mean.astype(np.float32), n=_fft_length(wd), axis=2)  # (N, R, F)
    dy_max = min(config.coarse_dy_px // config.coarse_row_downsample, rows - 1)
    dys = np.arange(-dy_max, dy_max + 1)
    inv_norms = _inverse(_window_norms(zero_mean, dys, _same_shifts(wd))).transpose(1, 0, 2)
    prepared = PreparedSet(
        count=n,
        width_px=image_set.width,
        fov_rad=image_set.fov_rad,
        camera_angle_rad=image_set.camera_angle_rad,
        shape_key=(
            *image_set.images.shape,
            image_set.fov_rad,
            image_set.keep_top_fraction,
            *(getattr(config, f) for f in _SHAPE_FIELDS),
            config.highpass_fraction,
            config.baseline,
            *config.zooms,
        ),
        template_rows=np.ascontiguousarray(np.conj(spectra).transpose(2, 0, 1), np.complex64),
        inv_template_norm=_inverse(np.sqrt(np.sum(zero_mean**2, axis=(1, 2)))),
        image_rows=np.ascontiguousarray(spectra.transpose(2, 1, 0), np.complex64),
        inv_window_norm=np.ascontiguousarray(inv_norms, dtype=np.float32),
        fine=_fine_spectra(fine_images, image_set.width),
        fine_images=Compact.of(fine_images, float(config.fine_downsample) ** 2),
        zoomed=tuple(
            _fine_spectra(_fine_scaled(_zoomed(image_set, zoom), config), image_set.width)
            for zoom in config.zooms
        ),
    )
    if config.baseline:
        prepared = replace(prepared, baseline=_baseline(prepared))
    return prepared


def _baseline(prepared: PreparedSet) -> float:
    """The set's similarity with itself at every cyclic offset but 0, averaged.

    Those are views of one junction 360/N degrees and more apart: different views of
    the same kind of pipe, lit the same way, seen by the same camera. They score about
    what different junctions score in this imagery (0.16-0.27 in ours and the
    paper's, by resolution and renderer), so subtracting it puts every imagery on one
    scale, learnt from each set alone.
    """
    n = prepared.count
    if n < 2:
        return 0.0
    values, _ = _zoomed_peaks(prepared, [(prepared, k) for k in range(1, n)])
    return float(values.mean())


_SHAPE_FIELDS = (
    "coarse_downsample",
    "coarse_row_downsample",
    "coarse_dy_px",
    "fine_downsample",
    "paper_resampling",
)


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


def _fine_spectra(fine: np.ndarray, full_width_px: int) -> FineSpectra:
    n, rows, width = fine.shape
    zero_mean = fine.astype(np.float64) - fine.mean(axis=(1, 2), keepdims=True)
    length = (_fft_length(rows), _fft_length(width))
    # Two stages so that the zero rows of the padding are never transformed along x.
    along_x = np.fft.rfft(zero_mean.astype(np.float32), n=length[1], axis=2)
    spectrum = np.fft.fft(along_x, n=length[0], axis=1)
    return FineSpectra(
        rows=rows,
        width=width,
        full_width_px=full_width_px,
        length=length,
        spectrum=spectrum,
        inv_norm=_inverse(np.sqrt(np.sum(zero_mean**2, axis=(1, 2)))),
        inv_window_norm=_inverse(_same_range_norms(zero_mean)).astype(np.float32),
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
    """
    n, rows, width = query.inv_window_norm.shape
    ramped = np.conj(query.spectrum) * _ramp(query.length, rows, width)
    product = np.empty((len(blocks), *ramped.shape), dtype=ramped.dtype)
    inv_window = np.empty((len(blocks), n, rows, width), dtype=np.float32)
    for b, (known, k) in enumerate(blocks):
        order = (np.arange(n) + k) % n
        np.multiply(ramped, known.spectrum[order], out=product[b])
        inv_window[b] = known.inv_window_norm[order]
    product = product.reshape(-1, *ramped.shape[1:])
    along_y = np.fft.ifft(product, axis=1)[:, :rows]
    ncc = np.fft.irfft(along_y, n=query.length[1], axis=2)[:, :, :width]
    ncc *= inv_window.reshape(-1, rows, width)
    ncc *= np.tile(query.inv_norm, len(blocks)).astype(np.float32)[:, None, None]
    best_row = np.argmax(ncc.reshape(len(ncc), -1), axis=1) // width
    value, column = _peaks_along_columns(ncc[np.arange(len(ncc)), best_row])
    shape = (len(blocks), n)
    return np.clip(value, -1.0, 1.0).reshape(shape), (column - width // 2).reshape(shape)


def _fine(prepared: PreparedSet) -> FineSpectra:
    assert prepared.fine is not None, "a database's set: use FastMatcher._refinable"
    return prepared.fine


def _zoomed_peaks(
    query: PreparedSet, blocks: list[tuple[PreparedSet, int]]
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_fine_peaks` of the blocks, each image pair at its best zoom.

    Without zooms this is the paper's comparison. With them, each pair is also
    compared with the query zoomed in and with the known set zoomed in (a camera
    nearer to, or farther from, the wall it faces), and keeps the highest peak and
    that peak's column shift.
    """
    values, columns = _fine_peaks(_fine(query), [(_fine(known), k) for known, k in blocks])
    for z, zoomed in enumerate(query.zoomed):
        for trial in (
            _fine_peaks(zoomed, [(_fine(known), k) for known, k in blocks]),
            _fine_peaks(_fine(query), [(known.zoomed[z], k) for known, k in blocks]),
        ):
            better = trial[0] > values
            values = np.where(better, trial[0], values)
            columns = np.where(better, trial[1], columns)
    return values, columns


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
        #: Refinement spectra of the last few refined known sets, rebuilt on demand.
        self._fine_cache: OrderedDict[int, PreparedSet] = OrderedDict()

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
        self._sets.append(_kept(prepared))
        return len(self._sets) - 1

    def kept_bytes(self) -> int:
        """Memory the database holds for its known sets (screening arrays as used,
        the compact refinement images, and any zoomed spectra)."""
        arrays = self._screening_arrays()
        total = 0 if arrays is None else sum(a.nbytes for a in arrays)
        for known in self._sets:
            if known.fine_images is not None:
                total += known.fine_images.values.nbytes
            total += sum(z.spectrum.nbytes + z.inv_window_norm.nbytes for z in known.zoomed)
        return total

    def _refinable(self, i: int) -> PreparedSet:
        """Known set ``i`` with its refinement spectra, from a small cache (they cost
        ten times the compact images to keep, and a few ms to rebuild)."""
        cached = self._fine_cache.get(i)
        if cached is not None:
            self._fine_cache.move_to_end(i)
            return cached
        known = self._sets[i]
        if known.fine is None:
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

    def match(self, query: PreparedSet, exclude: int | None = None) -> list[SetMatch]:
        """Algorithm 2 between the query (as A) and every known set (as B).

        The known set ``exclude`` (if any) cannot be the answer: it is screened but
        never refined, so the refinement goes to the sets that can.
        """
        peaks, shifts = self.screen(query)
        if peaks.shape[0] == 0:
            return []
        scores = _offset_scores(peaks)  # (M, N)
        baselines = [(query.baseline + known.baseline) / 2.0 for known in self._sets]
        # Rotations between the robots' headings, not between the sweeps' cameras.
        turns = [query.camera_angle_rad - known.camera_angle_rad for known in self._sets]
        matches = _screened_matches(scores, shifts, query.fov_rad, query.width_px, baselines, turns)
        order = sorted(
            (i for i in range(len(matches)) if i != exclude),
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
            for k in np.argsort(-scores[i], kind="stable")[
                : n_offsets if rank == 0 else n_runner_up
            ]
        ]
        if blocks:
            values, columns = _zoomed_peaks(query, [(self._refinable(i), k) for i, k in blocks])
        j = np.arange(n)
        for i in order[: self.config.refine_candidates]:
            peak_ncc = np.full((n, n), -np.inf)
            peak_dx = np.zeros((n, n))
            for b, (owner, k) in enumerate(blocks):
                if owner == i:
                    fine = self._refinable(i).fine
                    assert fine is not None
                    peak_ncc[j, (j + k) % n] = values[b]
                    peak_dx[j, (j + k) % n] = columns[b] * (fine.full_width_px / fine.width)
            refined = best_offset(peak_ncc, peak_dx, query.fov_rad, query.width_px)
            matches[i] = replace(refined, similarity=refined.similarity - baselines[i]).turned(
                turns[i]
            )
        return matches


#: Known sets whose refinement spectra a matcher keeps at hand.
_FINE_CACHE = 8


def _kept(prepared: PreparedSet) -> PreparedSet:
    """What a database keeps of a set: no query-side screening rows (the matcher's
    arrays hold its searched rows), no spectra when the compact images can rebuild them."""
    empty = np.zeros((0,), dtype=np.complex64)
    rebuildable = prepared.fine_images is not None
    return replace(
        prepared,
        template_rows=empty,
        image_rows=empty,
        inv_window_norm=np.zeros((0,), dtype=np.float32),
        fine=None if rebuildable else prepared.fine,
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
    everything = replace(
        base, refine_candidates=len(sets), refine_offsets=offsets, runner_up_offsets=offsets
    )
    for i in range(len(sets) - 1):
        later = FastMatcher(everything)
        for p in prepared[i + 1 :]:
            later.add(p)
        for offset, match in enumerate(later.match(prepared[i])):
            out[(i, i + 1 + offset)] = match
    return out
