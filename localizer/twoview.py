"""Two-view geometry between two sweeps: the rotation between them, and a check.

The paper turns the NCC peak's pixel shift into a rotation. That is exact only when
the two sweeps were taken from the same spot. A few centimetres off centre, walls
10 cm away shift by tens of pixels one way on one side of the robot and the other
way on the other: the parallax. The mean over the six image pairs cancels it only
when every wall is equally far, and pipe openings are far while walls are near;
on the ``noise`` condition half the same-junction pairs were off by more than
0.01 rad.

Here each sweep is a central panorama (the camera turns about a vertical axis
through its own centre), so every keypoint is a bearing, a unit vector in the
robot's heading frame. Between two sweeps of one junction the robot turned by
``rotation_rad`` about the vertical and moved horizontally by ``t`` (unknown
length). Every pair of matching bearings ``a`` (query) and ``b`` (known set)
then obeys the epipolar constraint ``a . (t x R b) = 0``, whatever the depth of
the point: the parallax is modelled, not averaged away. Two unknowns remain,
the rotation and the direction of ``t``, found by a grid search that counts the
pairs within a pixel or so of the constraint (robust to wrong matches), then
refined by Gauss-Newton on those inliers.

A pure rotation (``t = 0``) still fixes ``rotation_rad``: keypoints above or
below the horizon leave a residual for any other rotation.

The constraint rests on the keypoints' elevations, so a robot standing a few
hundredths of a radian off level (the paper's own image sets: pitch and roll up to
0.05 rad) tilts one panorama against the other by tens of pixels, and the planar
fit then picks a rotation up to 0.19 rad off. So the planar fit is refined once
more with the relative tilt free: a 3D rotation (heading change, relative roll
and pitch) and a 3D direction of motion, by Gauss-Newton on inliers taken within
a tolerance that shrinks from 16 to 1.5 pixels. It is kept only if it fits
clearly more keypoints than the planar fit (level sweeps gain nothing from it).
On those sets it takes the rotation error across entries from 0.077 rad on average
(max 0.19) to 0.009. The inlier count that checks a match stays the planar fit's.

The inlier count is also a check that both sweeps show the same place: matched
keypoints of two different junctions do not fit one motion. Keypoints are ORB's
(OpenCV), matched by Hamming distance with Lowe's ratio test; given a rotation
guess, each image only with the images of the other sweep that can overlap it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from pipemap.localizer.epipolar import (
    _gauss_newton,
    _grid_counts,
    _levelling,
    _planar_residuals,
    _residuals,
    _tilted,
)
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.keymatch import MatchCache, overlapping_images
from pipemap.localizer.similarity import wrap_angle_rad
from pipemap.localizer.stages import _asked_stages, _coarse_start, _staged_matches

__all__ = [
    "StoredFeatures",
    "SweepFeatures",
    "TwoViewConfig",
    "TwoViewFit",
    "detection_factor",
    "fit_two_view",
    "overlapping_images",
    "stored_features",
    "sweep_features",
]


@dataclass(frozen=True)
class TwoViewConfig:
    """Settings of keypoints, matching and the motion fit."""

    #: ORB keypoints kept per image.
    keypoints_per_image: int = 800
    #: Wider images are reduced by an integer factor to at most this width before
    #: ORB sees them, and keep ``reduced_keypoints_per_image`` each (see
    #: :func:`stored_features`).
    detect_width_px: int = 200
    reduced_keypoints_per_image: int = 250
    #: The least brightness step around a FAST corner, in grey levels, for images
    #: ORB sees at their own size and for reduced ones. A higher threshold keeps fewer,
    #: clearer corners and costs less (at 400 px, 20 halves ORB's time and quarters
    #: the matching), but weak revisits lose inliers: over the 40 logs of
    #: ``experiments/maps.toml`` (578 decisions), 10 kept every decision, 12 and 15
    #: lost one, 20 three. See docs/performance.md.
    fast_threshold: int = 5
    reduced_fast_threshold: int = 5
    #: Lowe's ratio: a match counts if its distance is below this share of the
    #: second-best one.
    ratio: float = 0.8
    #: With a rotation guess, match each image only with the images of the other
    #: sweep it can overlap (see :func:`overlapping_images`), this far beyond the
    #: field of view: half the Hamming distances or fewer to compute.
    overlap_only: bool = True
    overlap_margin_rad: float = 0.6
    #: Lowe's ratio when matching only overlapping images: fewer keypoints compete
    #: for second best there, so ambiguous matches pass more easily at ``ratio``.
    overlap_ratio: float = 0.8
    #: Matching in stages: the known sweep's keypoints ``k`` with ``k % gate_every``
    #: = 0 first, then 1, ...; after stage ``s`` (of ``gate_every``) the fit gives up
    #: when the matches so far have a best count on the coarse grid below
    #: ``gate_share`` of ``min_inliers * s / gate_every`` (what that share of a fit
    #: that just passes would give; no gate where the first stage's is below 3, as
    #: for the plain fit's 12: any two matches fit some motion). All stages together
    #: are the very matches of one, put back in its order, so a fit that passes every
    #: gate is unchanged. The paper's 55 pairs at 400 px (every image against every
    #: image), after the first quarter: different junctions reach 7 at most on that
    #: grid, same ones 20 or more (95 or more inliers in the end). ``gate_every = 1``:
    #: one stage.
    #:
    #: ``gate_share`` 0.7 (0.5 before issue 17's stop 29): over every fit of 107
    #: replayed logs (the 80 of ``experiments/maps.toml``, the 3 stored, 24 older
    #: reference ones at 96 to 400 px), the paper's sets and the distractors of
    #: ``benchmarks/bench_localizer.py``, 3 023 fits, 755 of them successful, each
    #: stage counted: the weakest successful fit reached 1.14 times its share
    #: (``min_inliers * s / gate_every``) at every stage, the failed ones 0.33 at the
    #: median after the first quarter, 0.67 at the 90th percentile. At 0.7 none of the
    #: successful fits stops, the failed ones match 30% of the known keypoints on
    #: average instead of 37% (a new junction among 100 known, 25% against 31%), and
    #: every one of those 107 logs gives the same map document.
    gate_every: int = 4
    gate_share: float = 0.7
    #: An early gate inside the first stage: its keypoints are matched in two halves
    #: (``k % (2 * gate_every)`` = 0, then = ``gate_every``), and after the first
    #: the fit gives up when the best count on the coarse grid is below this share
    #: of ``min_inliers / (2 * gate_every)`` (none where that is below 3: for 48
    #: inliers asked, 0.9 gives 5; the map's own junction, asked 24, gets none). It
    #: only gives up: the first stage's matches, every later gate and the fit of a
    #: candidate that passes it are as without it. Issue 17, stop 31: over the same
    #: 3 023 fits as ``gate_share``'s, the weakest successful fit asked 48 reached 9
    #: after the eighth (1.5 times ``min_inliers / 8``, 1.67 times this gate), and
    #: failed fits of the benchmark's new junctions matched 14% of the known
    #: keypoints instead of 25%. 0: no early gate.
    early_gate_share: float = 0.9
    #: Stop matching after a stage whose count on the coarse grid (a gate's, made
    #: anyway) reaches this many times ``min_inliers``, and fit those matches alone;
    #: if that fit fails, every stage is matched. Only for levelled sweeps (or
    #: ``tilt`` off): the tilted refinement needs every keypoint. A rival fit of
    #: another turn matches as many stages (``stage_limit``, :mod:`localizer.verify`).
    #: 0: every stage. Issue 17, stop 33 (docs/performance.md): 4 kept every
    #: decision of 107 logs, fitted 405 of 709 revisits on a quarter, and cut the
    #: 200 px 100-junction log's mean decision by a fifth; revisits' rotation error
    #: 0.00135 -> 0.00165 rad on average (2 kept 0.00195, with errors to 0.03).
    accept_share: float = 4.0
    #: Match only the first this many stages (0: all); the gates and ``min_inliers``
    #: then apply to those stages' keypoints.
    stage_limit: int = 0
    #: The coarse search on all matches (see :func:`fit_two_view`) is made only this
    #: many rotation steps either side of the best rotation of the last gate's grid,
    #: when that grid found at least twice what its gate asked: the peak a quarter
    #: of the keypoints found so clearly is the peak of all of them, and the search
    #: everywhere else cost a revisit 4-5 ms. 0: everywhere, always.
    local_steps: int = 10
    #: Rotation searched within this angle of the peak of the matches' azimuth
    #: differences (parallax at 3 cm off centre reaches about 0.3 rad).
    search_rad: float = 0.3
    #: Search around the matches' azimuth peak as well as the guess (off: a fit that
    #: tests one rotation, see :mod:`localizer.verify`).
    around_peak: bool = True
    #: Grid steps of the search: rotation, and direction of motion over [0, pi).
    rotation_steps: int = 121
    direction_steps: int = 90
    #: An inlier is within this many pixels (at the image centre) of the constraint.
    inlier_px: float = 1.5
    #: Fewer inliers than this, or than this share of the matches, give no fit. Wrong
    #: matches fit some motion by chance: 4% of 600 random ones did. Matches of
    #: one junction fit at 16% or more (the paper's image sets from different
    #: entries; 50% and more in pipemap's).
    min_inliers: int = 12
    min_inlier_share: float = 0.1
    refine_iterations: int = 6
    #: Refine the rotation with the relative tilt of the two sweeps free (unless both
    #: were levelled by their IMU readings, see :attr:`imu_level`).
    tilt: bool = True
    #: Its tolerances, in pixels, tightened in turn (a few iterations each), and the
    #: largest relative tilt taken as real (more is a fit gone astray).
    tilt_tolerances_px: tuple[float, ...] = (16.0, 8.0, 4.0, 2.0, 1.5)
    tilt_iterations: int = 4
    max_tilt_rad: float = 0.2
    #: The tilted fit replaces the planar one only if it has this many times its
    #: inliers: three more unknowns must explain more. Level sweeps (pipemap's
    #: simulator) gain 0.87-1.04 times, the paper's tilted sets 1.32 times or more.
    tilt_min_gain: float = 1.2
    #: Level each sweep's bearings by its IMU's roll and pitch
    #: (:attr:`ImageSet.imu_tilt_rad`) before matching: the planar fit then holds for
    #: a robot off level, and the tilt refinement (:attr:`tilt`), left with only the
    #: IMU's error, is made only when a sweep has no reading.
    imu_level: bool = True


@dataclass(frozen=True)
class SweepFeatures:
    """The keypoints of one sweep as bearings in the robot's heading frame.

    ``bearings`` is ``(M, 3)``: x ahead, y left, z up, unit length.
    ``descriptors`` is ``(M, 32)`` uint8 (ORB). ``pixel_rad`` is the angle one pixel
    subtends at the image centre.

    ``image`` (the index of the image each keypoint came from), ``image_azimuth_rad``
    (where each image looks, in the heading frame) and ``fov_rad`` let
    :func:`fit_two_view` match only the images that can overlap; without them
    (``None``) every keypoint is matched with every other.
    """

    bearings: np.ndarray
    descriptors: np.ndarray
    pixel_rad: float
    image: np.ndarray | None = None
    image_azimuth_rad: np.ndarray | None = None
    fov_rad: float | None = None
    #: The bearings were levelled by the sweep's IMU reading (level already).
    levelled: bool = False

    def __len__(self) -> int:
        return len(self.bearings)


@dataclass(frozen=True)
class TwoViewFit:
    """The motion between two sweeps found from their matched keypoints.

    ``rotation_rad`` is from the query's heading to the known set's (the convention
    of :attr:`localizer.similarity.SetMatch.rotation_rad`). ``direction_rad`` is the
    direction of the line between the two spots in the query's heading frame (modulo
    pi: the constraint does not tell forward from back). ``inliers`` of ``matches``
    fit the planar motion. ``tilt_rad`` is how far one sweep's vertical leans from
    the other's, as the tilted refinement found it (0.0 without one).
    """

    rotation_rad: float
    direction_rad: float
    inliers: int
    matches: int
    tilt_rad: float = 0.0
    #: The stages of the known sweep's keypoints matched (``gate_every`` in all)
    #: when fewer than all were (:attr:`TwoViewConfig.accept_share`, ``stage_limit``);
    #: ``inliers`` and ``matches`` count those. ``None``: every keypoint.
    stages: int | None = None

    def turned(self, angle_rad: float) -> TwoViewFit:
        """The same fit with the query's heading turned by ``angle_rad`` (for a probe
        sweep taken after turning; see :meth:`SetMatch.turned`)."""
        return replace(self, rotation_rad=wrap_angle_rad(self.rotation_rad + angle_rad))


def _gray_u8(image: np.ndarray) -> np.ndarray:
    lo, hi = float(image.min()), float(image.max())
    if hi <= 255.0 and lo >= 0.0:
        return np.ascontiguousarray(np.rint(image), dtype=np.uint8)
    # Images not on a 0..255 scale: stretch them to it (ORB reads 8-bit images).
    scale = 255.0 / (hi - lo) if hi > lo else 0.0
    return np.ascontiguousarray(np.rint((image - lo) * scale), dtype=np.uint8)


def _orb(keypoints: int, width_px: int, fast_threshold: int) -> cv2.ORB:
    # ORB skips a border as wide as its patch; small images need a smaller patch.
    patch = int(min(31, max(7, width_px // 12)))
    return cv2.ORB.create(
        nfeatures=keypoints,
        edgeThreshold=patch,
        patchSize=patch,
        fastThreshold=fast_threshold,
    )


@dataclass(frozen=True)
class StoredFeatures:
    """The keypoints of one sweep as a known junction keeps them: compact, lossless.

    ``points`` are ORB's own float32 pixel positions ``(M, 2)`` in the image ORB saw
    (reduced by ``factor``), image by image, ``per_image`` how many of them each
    image gave (:attr:`image` spells out the image of each) and ``descriptors`` the
    ``(M, 32)`` uint8 ORB descriptors: 40 bytes a keypoint, against 56 for bearings
    in float64. :meth:`features` gives back the very bearings :func:`sweep_features`
    gives.
    """

    points: np.ndarray
    per_image: np.ndarray
    descriptors: np.ndarray
    count: int
    height: int
    width: int
    fov_rad: float
    camera_angle_rad: float
    factor: int
    #: The IMU's (roll, pitch) of the sweep: the bearings are levelled by it
    #: (``None``: no reading, or not used).
    imu_tilt_rad: tuple[float, float] | None = None

    @property
    def nbytes(self) -> int:
        """Memory held by the arrays."""
        return int(self.points.nbytes + self.per_image.nbytes + self.descriptors.nbytes)

    @property
    def image(self) -> np.ndarray:
        """The index of the image each keypoint came from, ``(M,)``."""
        index = np.arange(self.count, dtype=np.uint8 if self.count <= 256 else np.uint16)
        image: np.ndarray = np.repeat(index, self.per_image)
        return image

    def __len__(self) -> int:
        return len(self.points)

    def features(self) -> SweepFeatures:
        """The keypoints as bearings in the heading frame (see :func:`sweep_features`)."""
        n, h, w = self.count, self.height, self.width
        focal_px = (w / 2.0) / math.tan(self.fov_rad / 2.0)
        pixel_rad = self.factor / focal_px
        looks = self.camera_angle_rad - np.arange(n, dtype=np.float64) * 2.0 * math.pi / n
        levelled = self.imu_tilt_rad is not None
        if len(self.points) == 0:
            empty = np.zeros((0, 3)), np.zeros((0, 32), np.uint8), pixel_rad
            return SweepFeatures(*empty, self.image, looks, self.fov_rad, levelled)
        image = self.image
        # OpenCV puts pixel 0's centre at 0.0; the image centre is at (w - 1) / 2.
        uv = self.points.astype(np.float64)
        if self.factor != 1:
            uv = (uv + 0.5) * self.factor - 0.5
        x = uv[:, 0] - (w - 1) / 2.0
        y = (h - 1) / 2.0 - uv[:, 1]
        step = image.astype(np.float64) * 2.0 * math.pi / n  # j * 2.0 * pi / n, as ever
        azimuth = self.camera_angle_rad - step - np.arctan2(x, focal_px)
        horizontal = np.hypot(focal_px, x)
        rays = np.stack([np.cos(azimuth) * horizontal, np.sin(azimuth) * horizontal, y], axis=1)
        bearings = rays / np.linalg.norm(rays, axis=1, keepdims=True)
        if self.imu_tilt_rad is not None and self.imu_tilt_rad != (0.0, 0.0):
            bearings = bearings @ _levelling(*self.imu_tilt_rad).T
        return SweepFeatures(
            bearings, self.descriptors, pixel_rad, image, looks, self.fov_rad, levelled
        )


def detection_factor(width_px: int, config: TwoViewConfig) -> int:
    """How much a sweep's images are reduced before ORB sees them: the smallest
    integer factor that brings the width to ``config.detect_width_px`` or less."""
    return max(1, -(-width_px // config.detect_width_px))


def stored_features(image_set: ImageSet, config: TwoViewConfig | None = None) -> StoredFeatures:
    """ORB keypoints of the kept part of every image of a sweep, compactly.

    Images wider than ``config.detect_width_px`` are first reduced by an integer
    factor (area averaging), and keep ``config.reduced_keypoints_per_image``
    keypoints each instead of ``config.keypoints_per_image``: at 400 px this costs
    a third of the time and memory, and pairs of one junction still fit with 94
    inliers or more against 11 at most for different ones (the paper's 55 pairs at
    400 px; 233 and 9 at full size with 800 keypoints an image).
    """
    config = config if config is not None else TwoViewConfig()
    return detected(*orb_input(image_set, config), config)


def orb_input(image_set: ImageSet, config: TwoViewConfig) -> tuple[StoredFeatures, np.ndarray]:
    """What ORB sees of a sweep (:func:`stored_features`): its :class:`StoredFeatures`
    with no keypoints yet, and the 8-bit images, ``(N, rows, cols)``, for :func:`detected`."""
    n, h, w = image_set.images.shape
    kept = list(image_set.cropped())  # the part the NCC matches (the rest may show the robot)
    factor = detection_factor(w, config)
    if factor > 1:
        size = (max(w // factor, 8), max(image_set.kept_rows // factor, 8))
        kept = [cv2.resize(np.asarray(im), size, interpolation=cv2.INTER_AREA) for im in kept]
    none = np.zeros((0, 2), np.float32), np.zeros(n, np.int32), np.zeros((0, 32), np.uint8)
    tilt = image_set.imu_tilt_rad if config.imu_level else None
    angles = image_set.fov_rad, image_set.camera_angle_rad
    frame = StoredFeatures(*none, n, h, w, *angles, factor, tilt)
    return frame, np.stack([_gray_u8(im) for im in kept])


def detected(frame: StoredFeatures, seen: np.ndarray, config: TwoViewConfig) -> StoredFeatures:
    """``frame`` with ORB's keypoints of the images ``seen`` (both :func:`orb_input`'s)."""
    reduced = frame.factor > 1
    per_image = config.reduced_keypoints_per_image if reduced else config.keypoints_per_image
    threshold = config.reduced_fast_threshold if reduced else config.fast_threshold
    orb = _orb(per_image, frame.width // frame.factor, threshold)
    points: list[np.ndarray] = [frame.points]
    counts = np.zeros(frame.count, dtype=np.int32)
    descriptors: list[np.ndarray] = [frame.descriptors]
    for j, image in enumerate(seen):
        keypoints, desc = orb.detectAndCompute(image, None)
        if desc is None or not keypoints:
            continue
        points.append(np.asarray(cv2.KeyPoint.convert(keypoints), dtype=np.float32).reshape(-1, 2))
        counts[j] = len(keypoints)
        descriptors.append(desc)
    arrays = np.concatenate(points), counts, np.concatenate(descriptors)
    return replace(frame, points=arrays[0], per_image=arrays[1], descriptors=arrays[2])


def sweep_features(image_set: ImageSet, config: TwoViewConfig | None = None) -> SweepFeatures:
    """ORB keypoints of the kept part of every image of a sweep, as bearings in the
    heading frame.

    Image ``j`` looks ``camera_angle_rad - j * 2 pi / N`` from the heading (the
    camera turns clockwise seen from above, as in the paper's sweeps); a keypoint
    at ``x`` pixels right of the centre is ``atan(x / f)`` further clockwise. See
    :func:`stored_features` for images wider than ``config.detect_width_px``.
    """
    return stored_features(image_set, config).features()


def fit_two_view(
    query: SweepFeatures,
    known: SweepFeatures,
    config: TwoViewConfig | None = None,
    guess_rad: float | None = None,
    cache: MatchCache | None = None,
) -> TwoViewFit | None:
    """The rotation and motion between two sweeps, or ``None`` when too few matched
    keypoints fit one motion (not the same place, or too little texture).

    The rotation is searched around the peak of the matches' azimuth differences
    and around ``guess_rad`` (the NCC's estimate, say), if given: near walls pull
    the peak by up to the parallax. With a guess (and ``config.overlap_only``), each
    image is matched only with the images of the other sweep that can overlap it.
    ``cache`` (a :class:`MatchCache` of this pair) keeps the keypoint distances for
    another fit of the same two sweeps: the same fit, fewer distances.

    A levelled pair whose first stages fit clearly may be fitted on them alone
    (:attr:`TwoViewConfig.accept_share`, :attr:`TwoViewFit.stages`).
    """
    config = config if config is not None else TwoViewConfig()
    if config.tilt and not (query.levelled and known.levelled):
        config = replace(config, accept_share=0.0)  # on the paper's sets: 0.05 rad off
    fit, stopped_early = _fit(query, known, config, guess_rad, cache)
    if fit is None and stopped_early:
        fit, _ = _fit(query, known, replace(config, accept_share=0.0), guess_rad, cache)
    return fit


def _fit(
    query: SweepFeatures,
    known: SweepFeatures,
    config: TwoViewConfig,
    guess_rad: float | None,
    cache: MatchCache | None,
) -> tuple[TwoViewFit | None, bool]:
    """:func:`fit_two_view`'s fit, and whether its matching stopped early."""
    overlap = None
    if guess_rad is not None and config.overlap_only:
        overlap = overlapping_images(query, known, guess_rad, config.overlap_margin_rad)
    ratio = config.ratio if overlap is None else config.overlap_ratio
    tolerance = config.inlier_px * max(query.pixel_rad, known.pixel_rad)
    staged = _staged_matches(query, known, ratio, overlap, guess_rad, config, tolerance, cache)
    if staged is None:
        return None, False
    stages = max(1, config.gate_every)
    stopped_early = staged.stages < _asked_stages(config)
    ia, ib = staged.found
    if len(ia) < config.min_inliers:
        return None, stopped_early
    a, b = query.bearings[ia], known.bearings[ib]
    needed = max(config.min_inliers, config.min_inlier_share * len(a))
    rotation, direction, centres = _coarse_start(query, known, staged, guess_rad, config, tolerance)
    directions = np.linspace(0.0, math.pi, config.direction_steps, endpoint=False)
    # Fine: Gauss-Newton on the inliers, which are chosen again each round.
    refined = _gauss_newton(
        _planar_residuals,
        a,
        b,
        np.array([rotation, direction]),
        tolerance,
        config.refine_iterations,
        needed,
    )
    if refined is None:
        return None, stopped_early
    rotation, direction = float(refined[0]), float(refined[1])
    inliers = np.abs(_residuals(a, b, rotation, direction)) < tolerance
    count = int(inliers.sum())
    if count < needed:
        return None, stopped_early
    fit = TwoViewFit(
        rotation_rad=wrap_angle_rad(rotation),
        direction_rad=float(np.mod(direction, math.pi)),
        inliers=count,
        matches=len(a),
        stages=staged.stages if staged.stages < stages else None,
    )
    if not config.tilt or (query.levelled and known.levelled):
        # Levelled by their IMUs, the two sweeps are left with only the IMU's error:
        # too little tilt for the refinement to find (it would not gain the inliers
        # it must), and 5-6 ms a revisit saved.
        return fit, stopped_early
    # The second start: the azimuth peak, with its best direction of motion.
    peak = centres[0]
    peak_counts = _grid_counts(a, b, np.array([peak]), config.direction_steps, tolerance)
    peak_direction = float(directions[int(np.argmax(peak_counts[0]))])
    pixel_rad = max(query.pixel_rad, known.pixel_rad)
    starts = [(rotation, direction), (peak, peak_direction)]
    return _tilted(a, b, fit, starts, config, pixel_rad), stopped_early
