"""One image set made ready for the matcher: everything that depends on it alone.

:func:`prepare` computes, once per set, the screening rows and window norms, the
refinement's spectra at the paper's quarter scale (kept compact by a database, see
:class:`Compact`), any zoomed spectra and the set's baseline; :func:`_zoomed_peaks`
compares blocks of image pairs of two prepared sets.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from pipemap.errors import LocalizerError
from pipemap.localizer import transforms
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.similarity import paper_scaled
from pipemap.localizer.spectra import (
    FineSpectra,
    _fft_length,
    _fine_peaks,
    _fine_spectra,
    _inverse,
    _same_shifts,
    _window_norms,
)

__all__ = ["Compact", "FastConfig", "PreparedSet", "prepare"]


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
    A known junction keeps them :meth:`packed`: box means of 8-bit pixels, 16 times,
    are at most 4080, which 12 bits hold (1.5 bytes a pixel).
    """

    values: np.ndarray
    scale: float
    #: The images' shape when ``values`` holds them packed, two in three bytes.
    shape: tuple[int, ...] | None = None

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

    def packed(self) -> Compact:
        """The same images in 12 bits a value where every value is below 4096 (two
        values in three bytes); otherwise (a lamp-lit sweep's finer grid, float
        images) this one."""
        values = self.values
        if self.shape is not None or values.dtype != np.uint16 or not values.size:
            return self
        if int(values.max()) >= 1 << 12:
            return self
        flat = values.ravel()
        if flat.size % 2:
            flat = np.append(flat, np.uint16(0))
        low, high = flat[0::2], flat[1::2]
        out = np.empty((low.size, 3), dtype=np.uint8)
        out[:, 0] = low & 0xFF
        out[:, 1] = (low >> 8) | ((high & 0xF) << 4)
        out[:, 2] = high >> 4
        return Compact(out, self.scale, values.shape)

    def _unpacked(self) -> np.ndarray:
        if self.shape is None:
            return self.values
        bytes3 = self.values.astype(np.uint16)
        flat = np.empty(2 * bytes3.shape[0], dtype=np.uint16)
        flat[0::2] = bytes3[:, 0] | ((bytes3[:, 1] & 0xF) << 8)
        flat[1::2] = (bytes3[:, 1] >> 4) | (bytes3[:, 2] << 4)
        return flat[: math.prod(self.shape)].reshape(self.shape)

    def images(self) -> np.ndarray:
        """The images, exactly as given to :meth:`of`."""
        if self.scale == 1.0:
            return np.asarray(self.values, dtype=np.float64)
        out: np.ndarray = self._unpacked().astype(np.float64) / self.scale
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

    @property
    def screenable(self) -> bool:
        """Whether the set has its screening arrays, as a query or a set to add to a
        :class:`localizer.fastmatch.FastMatcher` needs them (see :func:`prepare`)."""
        return self.template_rows.size > 0 and self.inv_window_norm.size > 0


#: Refinement images that are no exact box mean of 8-bit pixels are put on this grid
#: of a grey level (see :func:`_refinement_images`).
GREY_GRID = 256.0


def _refinement_images(images: np.ndarray, config: FastConfig) -> tuple[np.ndarray, Compact]:
    """The refinement's images, and the compact form a known junction keeps of them.

    Box means of 8-bit pixels (evenly lit sweeps, the paper's image sets) are kept
    exactly, in 2 bytes a pixel. A lamp-lit sweep, divided by its illumination
    (:mod:`localizer.illumination`), has float32 quotients instead, which took 8 bytes
    a pixel: 234 KiB of the 296 KiB a junction kept at 400 px. Such images, where
    every pixel lies in 0..255, are rounded to 1/256 of a grey level (a pixel moves by
    1/512 at most) and kept in 2 bytes as well; the query's refinement uses the same
    rounded images, so both sides of a pair see the same pixels. Over 107 replayed
    logs, with and without the two-view check deciding, no decision changed, and
    similarities moved by 1.6e-5 at most. Images beyond 0..255 are kept as they are,
    as float64.
    """
    exact = Compact.of(images, float(config.fine_downsample) ** 2)
    if exact.values.dtype == np.uint16 or not images.size:
        return images, exact
    if float(images.min()) < 0.0 or float(images.max()) > 255.0:
        return images, exact
    steps = np.rint(images * GREY_GRID)  # whole steps, 0..65280: exact in uint16
    return steps / GREY_GRID, Compact(steps.astype(np.uint16), GREY_GRID)


def _area_downsampled(images: np.ndarray, row_factor: int, col_factor: int) -> np.ndarray:
    """The screening's images: ``images`` reduced by about the factors, each output
    pixel the mean of the input area it covers (what OpenCV's ``INTER_AREA`` does).

    As two products with weight matrices (:func:`_area_weights`), rows first in
    float32 (as OpenCV sums float32 images), then columns in float64: a seventh of
    ``cv2.resize``'s time, whose general path (a row factor such as 200 / 12) took
    0.18 ms a 400 px image. The two differ by float32 rounding, 4e-5 grey levels at
    most.
    """
    if row_factor == col_factor == 1:
        return images.astype(np.float64)
    n, h, w = images.shape
    hd, wd = max(h // row_factor, 2), max(w // col_factor, 2)
    rows, cols = _area_weights(h, hd), _area_weights(w, wd)
    reduced = np.matmul(rows.astype(np.float32), np.asarray(images, dtype=np.float32))
    out: np.ndarray = np.matmul(reduced.astype(np.float64), cols.T)
    return out


@functools.lru_cache(maxsize=8)
def _area_weights(size: int, reduced: int) -> np.ndarray:
    """``(reduced, size)``: the share of each input pixel in each output pixel when a
    line of ``size`` pixels is reduced to ``reduced`` by area averaging (output ``i``
    covers ``[i s, (i + 1) s)`` with ``s = size / reduced``; each row sums to 1)."""
    scale = size / reduced
    edges = np.arange(reduced + 1) * scale
    start = np.maximum(edges[:-1, None], np.arange(size)[None, :])
    stop = np.minimum(edges[1:, None], np.arange(1, size + 1)[None, :])
    weights: np.ndarray = np.clip(stop - start, 0.0, None) / scale
    weights.setflags(write=False)
    return weights


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


def config_key(config: FastConfig) -> tuple[float, ...]:
    """The settings a prepared set depends on, as the end of its ``shape_key``."""
    return (
        *(getattr(config, f) for f in _SHAPE_FIELDS),
        config.highpass_fraction,
        config.baseline,
        *config.zooms,
    )


def prepare(
    image_set: ImageSet, config: FastConfig, refinement: bool = True, screening: bool = True
) -> PreparedSet:
    """Precompute everything the fast path needs of one image set.

    Without ``refinement`` the refinement spectra are left out (``fine`` is None, unless
    the baseline needs them), as :func:`localizer.pairwise.for_pairs` would drop them:
    whoever refines the set builds them from its compact images. Without
    ``screening`` the screening arrays are empty (:attr:`PreparedSet.screenable` is
    False): for a set whose every offset is refined, as ``pipemap match`` refines them,
    which never screens it (3 ms of the 4 a set of 800 px took to prepare).
    """
    if config.fine_downsample > image_set.width // 2:
        raise LocalizerError(
            f"downsampling by {config.fine_downsample} (--downsample) leaves less than two "
            f"pixels of a {image_set.width} px wide image: at most {image_set.width // 2}"
        )
    if config.highpass_fraction > 0.0:
        image_set = _high_passed(image_set, config.highpass_fraction * image_set.width)
    cropped = image_set.cropped()
    fine_images, kept_fine = _refinement_images(_fine_scaled(cropped, config), config)
    screen = _screening(cropped, config) if screening else _NO_SCREENING
    prepared = PreparedSet(
        count=image_set.count,
        width_px=image_set.width,
        fov_rad=image_set.fov_rad,
        camera_angle_rad=image_set.camera_angle_rad,
        shape_key=(
            *image_set.images.shape,
            image_set.fov_rad,
            image_set.keep_top_fraction,
            *config_key(config),
        ),
        template_rows=screen[0],
        inv_template_norm=screen[1],
        image_rows=screen[2],
        inv_window_norm=screen[3],
        # Searched only by its own baseline; in a database it is rebuilt from
        # ``fine_images`` (``FastMatcher._refinable``).
        fine=(
            _fine_spectra(fine_images, image_set.width, searched=config.baseline)
            if refinement or config.baseline
            else None
        ),
        fine_images=kept_fine,
        zoomed=tuple(
            _fine_spectra(_fine_scaled(_zoomed(image_set, zoom), config), image_set.width)
            for zoom in config.zooms
        ),
    )
    if config.baseline:
        prepared = replace(prepared, baseline=_baseline(prepared))
    return prepared


def _screening(
    cropped: np.ndarray, config: FastConfig
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The screening arrays of :class:`PreparedSet` for the kept part of a set's images:
    template rows, template norms, searched rows and window norms."""
    small = _area_downsampled(cropped, config.coarse_row_downsample, config.coarse_downsample)
    rows, wd = small.shape[1:]
    zero_mean = small - small.mean(axis=(1, 2), keepdims=True)
    spectra = transforms.rfft(zero_mean.astype(np.float32), n=_fft_length(wd), axis=2)  # (N, R, F)
    dy_max = min(config.coarse_dy_px // config.coarse_row_downsample, rows - 1)
    dys = np.arange(-dy_max, dy_max + 1)
    inv_norms = _inverse(_window_norms(zero_mean, dys, _same_shifts(wd))).transpose(1, 0, 2)
    return (
        np.ascontiguousarray(np.conj(spectra).transpose(2, 0, 1), np.complex64),
        _inverse(np.sqrt(np.sum(zero_mean**2, axis=(1, 2)))),
        np.ascontiguousarray(spectra.transpose(2, 1, 0), np.complex64),
        np.ascontiguousarray(inv_norms, dtype=np.float32),
    )


#: The screening arrays of a set prepared without them (see :func:`prepare`).
_NO_SCREENING = (
    np.zeros((0, 0, 0), dtype=np.complex64),
    np.zeros((0,)),
    np.zeros((0, 0, 0), dtype=np.complex64),
    np.zeros((0, 0, 0), dtype=np.float32),
)


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
