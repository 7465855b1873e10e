"""The image set: what the robot sees at one junction.

A sweep of N grayscale images taken by a camera turning about the vertical axis
in N equal steps. The images are in sweep order; the step is ``2*pi/N``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pipemap.errors import LocalizerError

__all__ = ["DEFAULT_FOV_RAD", "DEFAULT_KEEP_TOP_FRACTION", "ImageSet"]

#: Horizontal field of view of the paper's camera: 80 degrees.
DEFAULT_FOV_RAD = math.radians(80.0)
#: The bottom half of each image shows the robot itself and is cropped away.
DEFAULT_KEEP_TOP_FRACTION = 0.5


@dataclass(frozen=True, eq=False)
class ImageSet:
    """N grayscale images of one sweep, in sweep order.

    ``images`` has shape ``(N, height, width)``, any real dtype; it is copied into a
    read-only float32 array. ``fov_rad`` is the camera's horizontal field of view and
    ``keep_top_fraction`` the part of each image, from the top, used for matching.

    ``camera_angle_rad`` is where the camera pointed for the first image, relative to
    the robot's heading (counter-clockwise positive; 0 in the paper, whose sweeps
    start straight ahead). Rotations between sets are reported between the robots'
    headings, so sets swept from different start angles compare correctly.

    ``imu_tilt_rad`` is the robot's (roll, pitch) during the sweep as its IMU reads
    them (roll about the forward axis, then pitch about the left one, nose down
    positive), (0, 0) for a level robot: the two-view check levels the sweep's
    bearings by it. ``None``, the default, for a sweep without an IMU reading (the
    paper's image sets): the two-view fit then estimates the tilt itself.
    """

    images: np.ndarray
    fov_rad: float = DEFAULT_FOV_RAD
    keep_top_fraction: float = DEFAULT_KEEP_TOP_FRACTION
    camera_angle_rad: float = 0.0
    imu_tilt_rad: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        arr = np.asarray(self.images)
        if arr.ndim != 3:
            raise LocalizerError(f"an image set needs shape (N, height, width), got {arr.shape}")
        n, h, w = arr.shape
        if n < 1:
            raise LocalizerError("an image set needs at least one image")
        if h < 4 or w < 4:
            raise LocalizerError(f"images of {w}x{h} pixels are too small to match")
        if not np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.complexfloating):
            raise LocalizerError(f"images must be real numbers, got dtype {arr.dtype}")
        if not (0.0 < self.fov_rad < 2.0 * math.pi):
            raise LocalizerError(f"fov_rad must be in (0, 2*pi), got {self.fov_rad}")
        if not (0.0 < self.keep_top_fraction <= 1.0):
            raise LocalizerError(
                f"keep_top_fraction must be in (0, 1], got {self.keep_top_fraction}"
            )
        if not math.isfinite(self.camera_angle_rad):
            raise LocalizerError(f"camera_angle_rad must be finite, got {self.camera_angle_rad}")
        if self.imu_tilt_rad is not None:
            roll, pitch = (float(v) for v in self.imu_tilt_rad)
            if not (abs(roll) < math.pi / 2 and abs(pitch) < math.pi / 2):
                raise LocalizerError(
                    f"imu_tilt_rad must be (roll, pitch) within 90 degrees, got {self.imu_tilt_rad}"
                )
            object.__setattr__(self, "imu_tilt_rad", (roll, pitch))
        if int(round(h * self.keep_top_fraction)) < 2:
            raise LocalizerError(
                f"keep_top_fraction {self.keep_top_fraction} keeps fewer than 2 rows of {h}"
            )
        frozen = np.array(arr, dtype=np.float32, copy=True)
        frozen.setflags(write=False)
        object.__setattr__(self, "images", frozen)

    @classmethod
    def from_images(
        cls,
        images: Sequence[np.ndarray],
        fov_rad: float = DEFAULT_FOV_RAD,
        keep_top_fraction: float = DEFAULT_KEEP_TOP_FRACTION,
        camera_angle_rad: float = 0.0,
    ) -> ImageSet:
        """Build a set from a sequence of equally sized 2-D grayscale images."""
        if len(images) == 0:
            raise LocalizerError("an image set needs at least one image")
        shapes = {np.shape(im) for im in images}
        if len(shapes) != 1:
            raise LocalizerError(f"images of one set differ in size: {sorted(shapes)}")
        stacked = np.stack([np.asarray(im) for im in images])
        return cls(stacked, fov_rad, keep_top_fraction, camera_angle_rad)

    @property
    def count(self) -> int:
        """Number of images N."""
        return int(self.images.shape[0])

    @property
    def height(self) -> int:
        """Full image height in pixels."""
        return int(self.images.shape[1])

    @property
    def width(self) -> int:
        """Image width in pixels."""
        return int(self.images.shape[2])

    @property
    def kept_rows(self) -> int:
        """Rows kept from the top of each image for matching."""
        return int(round(self.images.shape[1] * self.keep_top_fraction))

    @property
    def step_rad(self) -> float:
        """Camera turn between consecutive images: 2*pi/N."""
        return 2.0 * math.pi / self.count

    def cropped(self) -> np.ndarray:
        """The part used for matching: a read-only ``(N, kept_rows, width)`` float32 view."""
        return self.images[:, : self.kept_rows, :]

    def check_comparable(self, other: ImageSet) -> None:
        """Raise :class:`LocalizerError` unless ``other`` can be matched with this set."""
        if self.images.shape != other.images.shape:
            raise LocalizerError(
                "image sets differ in shape: "
                f"{self.count}x{self.width}x{self.height} vs "
                f"{other.count}x{other.width}x{other.height} (images x width x height)"
            )
        if self.fov_rad != other.fov_rad or self.keep_top_fraction != other.keep_top_fraction:
            raise LocalizerError("image sets differ in field of view or kept fraction")
