"""Image-set similarity as the paper's Algorithm 2 defines it: the reference.

The paper's recipe, step by step (its authors' code does the same):

1. each image is greyscale, and only its top half is kept (the bottom half shows
   the robot);
2. that half is resized to a quarter in each direction (:func:`paper_scaled`:
   area averaging, a 4x4 box mean when the size divides by 4);
3. for two image sets A and B of N images and every cyclic offset k, image j of A
   is compared with image (j + k) mod N of B by zero-mean normalized
   cross-correlation with local normalization (Lewis' "fast normalized
   cross-correlation", the ``normxcorr2`` of image processing toolboxes), over
   the "same" range of shifts:

    c(dy, dx) = sum_{y,x} T(y, x) * B(y + dy, x + dx)
    NCC(dy, dx) = c(dy, dx) / sqrt(sum T^2 * [S2 - S1^2 / n])

   where T is image j of A minus its mean, B is image (j + k) of B minus its mean and
   zero outside the image, S1 and S2 are the sums of B and B^2 over the
   template-sized window at (dy, dx), and n is the template's pixel count. Shifts
   cover ``-H/2 <= dy < H/2`` and ``-W/2 <= dx < W/2`` (H, W: the quarter-scale size);
4. the peak NCC of each pair and the column shift of that peak are averaged over
   j; the best k gives the similarity S, the image shift I = k and the pixel shift
   P (reported in full-resolution pixels, 4 per quarter-scale pixel). The relative
   rotation of B's sweep with respect to A's is ``I * 2*pi/N + P * fov / W``.

Two readings of ``normxcorr2`` that are *not* the paper's were measured on the 55
pairs of the paper's shared image sets (``docs/paper_similarity.md``): without
step 2 (pipemap's reference before issue 17) the shared pair ``1_active`` against
``2_noise`` scores 0.357, not 0.373; with the toolbox's "full" output (every
partial overlap, the image padded with black) different junctions score 0.448 on
average and all 19 different-junction pairs pass 0.36, where the paper reports
0.276 +- 0.028 and separates the two classes at 0.36.

This module is plain on purpose: one 2-D correlation per image pair, written to be
checked by eye. :mod:`localizer.fastmatch` is the production path and is
validated against it (within 0.005 on every shared pair).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from types import ModuleType

import cv2
import numpy as np

from pipemap.localizer.imageset import ImageSet

__all__ = [
    "PAPER_SCALE",
    "PairPeak",
    "SetMatch",
    "best_offset",
    "ncc_same",
    "pair_peak",
    "paper_scaled",
    "pinhole_rotation_rad",
    "reference_match",
    "relative_rotation_rad",
    "sums_from_integral",
    "window_sums",
    "wrap_angle_rad",
]


#: The paper matches images resized to a quarter of their size in each direction.
PAPER_SCALE = 4


def paper_scaled(images: np.ndarray, factor: int = PAPER_SCALE) -> np.ndarray:
    """Images ``(N, h, w)`` resized by ``1/factor`` in each direction, as float64.

    Area averaging (OpenCV's ``INTER_AREA``): a ``factor x factor`` box mean when
    the size divides by ``factor``, so every output pixel is a plain mean of the
    input. Never smaller than 2x2. The reference and the fast path both call this,
    so they see the same pixels.
    """
    n, h, w = images.shape
    hd, wd = max(h // factor, 2), max(w // factor, 2)
    if (hd, wd) == (h, w):
        return np.asarray(images, dtype=np.float64)
    out = np.empty((n, hd, wd), dtype=np.float64)
    for i in range(n):
        out[i] = cv2.resize(
            np.asarray(images[i], dtype=np.float32), (wd, hd), interpolation=cv2.INTER_AREA
        )
    return out


@dataclass(frozen=True)
class PairPeak:
    """Peak of the NCC of one image pair: value and shift of the peak in pixels."""

    ncc: float
    dx_px: float
    dy_px: float


@dataclass(frozen=True)
class SetMatch:
    """Similarity of two image sets and the rotation between their sweeps.

    ``similarity`` is S of Algorithm 2 (mean peak NCC at the best offset),
    ``image_shift`` the best cyclic offset I, ``pixel_shift`` the mean horizontal
    peak shift P in full-resolution pixels, and ``rotation_rad`` the relative
    rotation ``I*2*pi/N + P*fov/W`` wrapped to (-pi, pi], both as the paper defines
    them. ``rotation_pinhole_rad`` is pipemap's better estimate of the same rotation:
    each image pair's peak shift is turned into an angle by the pinhole model, and
    the median over the pairs is taken (see :func:`pinhole_rotation_rad`).
    ``refined`` is False only for a fast-path match that was screened, not refined.
    """

    similarity: float
    image_shift: int
    pixel_shift: float
    rotation_rad: float
    rotation_pinhole_rad: float
    refined: bool = True

    def turned(self, angle_rad: float) -> SetMatch:
        """The same match with both rotation estimates turned by ``angle_rad``.

        Used to go from the rotation between two sweeps' cameras to the rotation
        between the robots' headings, when the sweeps started at different camera
        angles: add ``a.camera_angle_rad - b.camera_angle_rad``.
        """
        if angle_rad == 0.0:
            return self
        return replace(
            self,
            rotation_rad=wrap_angle_rad(self.rotation_rad + angle_rad),
            rotation_pinhole_rad=wrap_angle_rad(self.rotation_pinhole_rad + angle_rad),
        )


def wrap_angle_rad(angle_rad: float) -> float:
    """Wrap an angle to (-pi, pi]."""
    wrapped = math.remainder(angle_rad, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def relative_rotation_rad(
    image_shift: int, pixel_shift: float, count: int, fov_rad: float, width_px: int
) -> float:
    """The paper's rotation estimate ``I*2*pi/N + P*fov/W``, wrapped to (-pi, pi]."""
    return wrap_angle_rad(image_shift * 2.0 * math.pi / count + pixel_shift * fov_rad / width_px)


def pinhole_rotation_rad(
    image_shift: int, pair_shifts_px: np.ndarray, count: int, fov_rad: float, width_px: int
) -> float:
    """Rotation from the per-pair peak shifts by the pinhole model, robustly.

    The paper maps a shift of P pixels to ``P * fov / W`` radians, as if every pixel
    subtended the same angle; in a pinhole camera of focal length
    ``f = (W/2) / tan(fov/2)`` a pixel at the centre subtends more. Two views turned
    by theta overlap around the middle of the turn, where a feature at +-theta/2 off
    axis moves by ``2 f tan(theta/2)`` pixels, so ``theta = 2 atan(P / 2f)``. The median
    over the N pairs ignores a pair whose peak latched onto the wrong structure. On
    the paper's image sets this cuts the mean error from 0.054 to about 0.02 rad.
    """
    focal_px = (width_px / 2.0) / math.tan(fov_rad / 2.0)
    angles = 2.0 * np.arctan(np.asarray(pair_shifts_px, dtype=np.float64) / (2.0 * focal_px))
    return wrap_angle_rad(image_shift * 2.0 * math.pi / count + float(np.median(angles)))


def window_sums(values: np.ndarray, dys: np.ndarray, dxs: np.ndarray) -> np.ndarray:
    """Sums of each image (zero outside it) over a window of its own size at each shift.

    ``values`` is one image ``(h, w)`` or a stack ``(..., h, w)``. Entry ``[..., iy, ix]``
    is the sum over rows ``dys[iy] .. dys[iy] + h - 1`` and columns ``dxs[ix] .. dxs[ix]
    + w - 1``. Computed from an integral image, so each entry is exact up to rounding.
    """
    h, w = values.shape[-2:]
    integral = np.zeros((*values.shape[:-2], h + 1, w + 1), dtype=np.float64)
    integral[..., 1:, 1:] = values.cumsum(axis=-2).cumsum(axis=-1)
    return sums_from_integral(integral, dys, dxs)


def sums_from_integral(integral: np.ndarray, dys: np.ndarray, dxs: np.ndarray) -> np.ndarray:
    """:func:`window_sums` given the integral images ``(..., h + 1, w + 1)``."""
    h, w = integral.shape[-2] - 1, integral.shape[-1] - 1
    rows = np.take(integral, np.clip(dys + h, 0, h), axis=-2) - np.take(
        integral, np.clip(dys, 0, h), axis=-2
    )
    sums: np.ndarray = np.take(rows, np.clip(dxs + w, 0, w), axis=-1) - np.take(
        rows, np.clip(dxs, 0, w), axis=-1
    )
    return sums


def _fft() -> ModuleType:
    """``scipy.fft``, imported on first use (0.15-0.3 s, and 28 MB resident): the
    reference transforms with it. The fast matcher calls the same compiled pocketfft
    without this import (:mod:`localizer.transforms`), with the same bits.

    Not ``numpy.fft``: numpy 2.4's single-precision transforms of the fast matcher's
    lengths (75 and 150: factors 3 and 5) took 5 to 7 times scipy's (a quarter-scale
    set's rows, 437 against 66 us); issue 17, stop 30, docs/performance.md.
    """
    from scipy import fft

    module: ModuleType = fft
    return module


def _correlate_same(image: np.ndarray, template: np.ndarray) -> np.ndarray:
    """``sum_{y,x} template[y, x] * image[y + dy, x + dx]`` over the "same" shift range.

    Correlation is convolution with the template flipped in both axes, done by real
    FFTs of the full linear size rounded up to a fast length. (This replaces scipy's
    ``signal.fftconvolve``: importing ``scipy.signal`` took 0.66 s of every command's
    start.) ``scipy.fft`` is imported on first use (:func:`_fft`).
    """
    sp_fft = _fft()
    h, w = image.shape
    full = (2 * h - 1, 2 * w - 1)
    size = [sp_fft.next_fast_len(n, True) for n in full]
    spectrum = sp_fft.rfftn(image, size) * sp_fft.rfftn(template[::-1, ::-1], size)
    product = sp_fft.irfftn(spectrum, size)
    top, left = (h - 1) // 2, (w - 1) // 2
    same: np.ndarray = product[top : top + h, left : left + w]
    return same


def ncc_same(template: np.ndarray, image: np.ndarray) -> np.ndarray:
    """Normalized cross-correlation map of two equally sized images, "same" mode.

    Entry ``[iy, ix]`` is the NCC at shift ``dy = iy - H//2``, ``dx = ix - W//2``: how
    well ``template[y, x]`` matches ``image[y + dy, x + dx]``. Values lie in [-1, 1];
    windows of zero variance give 0.
    """
    if template.shape != image.shape or template.ndim != 2:
        raise ValueError(f"need two equal 2-D shapes, got {template.shape} and {image.shape}")
    t = template.astype(np.float64) - template.mean()
    b = image.astype(np.float64) - image.mean()
    h, w = t.shape
    numerator = _correlate_same(b, t)
    dys = np.arange(h) - h // 2
    dxs = np.arange(w) - w // 2
    s1 = window_sums(b, dys, dxs)
    s2 = window_sums(b * b, dys, dxs)
    local_var = np.maximum(s2 - s1 * s1 / t.size, 0.0)
    denominator = np.sqrt(local_var * float(np.sum(t * t)))
    out = np.zeros_like(numerator)
    # Below this the window is flat and the quotient is rounding noise.
    ok = denominator > 1e-9 * max(float(denominator.max()), 1e-300)
    out[ok] = numerator[ok] / denominator[ok]
    clipped: np.ndarray = np.clip(out, -1.0, 1.0)
    return clipped


def pair_peak(template: np.ndarray, image: np.ndarray) -> PairPeak:
    """Peak of :func:`ncc_same`; ties go to the first in row-major order."""
    ncc = ncc_same(template, image)
    iy, ix = np.unravel_index(int(np.argmax(ncc)), ncc.shape)
    h, w = ncc.shape
    return PairPeak(float(ncc[iy, ix]), float(ix - w // 2), float(iy - h // 2))


def best_offset(
    peak_ncc: np.ndarray, peak_dx: np.ndarray, fov_rad: float, width_px: int
) -> SetMatch:
    """Algorithm 2's choice of offset from the per-pair peaks.

    ``peak_ncc[j, m]`` and ``peak_dx[j, m]`` (full-resolution pixels) hold the peak of
    image j of A against image m of B. For each k the pairs ``(j, (j+k) mod N)`` are
    averaged; the k of highest mean NCC wins, the lowest k on a tie.
    """
    n = peak_ncc.shape[0]
    j = np.arange(n)
    cols = (j[None, :] + j[:, None]) % n  # row k holds (j + k) mod N
    sims = peak_ncc[j[None, :], cols].mean(axis=1)
    shifts = peak_dx[j[None, :], cols].mean(axis=1)
    k = int(np.argmax(sims))
    return SetMatch(
        similarity=float(sims[k]),
        image_shift=k,
        pixel_shift=float(shifts[k]),
        rotation_rad=relative_rotation_rad(k, float(shifts[k]), n, fov_rad, width_px),
        rotation_pinhole_rad=pinhole_rotation_rad(k, peak_dx[j, cols[k]], n, fov_rad, width_px),
    )


def reference_match(a: ImageSet, b: ImageSet) -> SetMatch:
    """Similarity of two image sets by the paper's definition (top half, quarter
    scale, "same"-range NCC); pixel shifts in full-resolution pixels."""
    a.check_comparable(b)
    ca, cb = paper_scaled(a.cropped()), paper_scaled(b.cropped())
    to_full_px = a.width / ca.shape[2]
    n = a.count
    peak_ncc = np.empty((n, n))
    peak_dx = np.empty((n, n))
    for j in range(n):
        for m in range(n):
            peak = pair_peak(ca[j], cb[m])
            peak_ncc[j, m] = peak.ncc
            peak_dx[j, m] = peak.dx_px * to_full_px
    match = best_offset(peak_ncc, peak_dx, a.fov_rad, a.width)
    return match.turned(a.camera_angle_rad - b.camera_angle_rad)
