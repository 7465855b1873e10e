"""A k-nearest-neighbour index over the known junctions' compact descriptors.

The screen of :mod:`localizer.fastmatch` correlates the query with every known
junction: one matrix product per frequency over all of them, then one record each,
so its cost grows with every junction known (at a thousand, more than the rest of
a decision). Above :data:`INDEX_ABOVE` known junctions the matcher screens only a
shortlist instead: the :data:`SHORTLIST` junctions whose descriptors are nearest the
query's, and the junctions the map expects (the caller names them).

A junction's descriptor is what its screening rows already hold, made blind to the
two things the screen searches over: the magnitude of each row's spectrum (blind to
a column shift, that is to a turn within an image) averaged over the sweep's images
(blind to the cyclic offset between two sweeps), on a log scale, centred and of
unit length. Nearest is the largest dot product: one matrix-vector product over all
known junctions, 64 to 200 numbers each, a few hundred times cheaper per junction
than the screen. It ranks the way the screen ranks only roughly, so it shortlists
generously and never decides: the screen and the refinement still score the
shortlist exactly as before.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

__all__ = ["INDEX_ABOVE", "SHORTLIST", "DescriptorIndex", "descriptor"]

#: Up to this many known junctions the screen is exhaustive (as it always was).
INDEX_ABOVE = 256
#: Junctions the index hands the screen, beyond those the map expects.
SHORTLIST = 64


#: Azimuth samples of the panorama a descriptor is made from, per image.
_BINS_PER_IMAGE = 16
#: Horizontal bands of the panorama (top to bottom of the kept image).
_BANDS = 4
#: Azimuthal frequencies kept (1 cycle per turn upward; the mean is dropped).
_FREQUENCIES = 12


def descriptor(images: np.ndarray, fov_rad: float) -> np.ndarray:
    """The descriptor of one sweep from its images ``(N, H, W)``, N evenly spaced over
    a turn: float32, centred, of unit length (zero when the sweep is flat).

    The middle ``2 pi / N`` of each image is resampled by azimuth into a panorama of
    ``_BANDS`` horizontal bands (each a column-mean profile), so a turn of the robot
    is a cyclic shift of every band by the same angle. What such a shift leaves
    unchanged: each band's Fourier magnitudes over the turn, and the cross-spectra
    between bands (their phase differences, which also tell a view from its mirror
    image); the low ``_FREQUENCIES`` of each, on a signed log scale.
    """
    n, height, width = images.shape
    focal_px = (width / 2.0) / np.tan(fov_rad / 2.0)
    step = 2.0 * np.pi / n
    # Bin edges by azimuth over the middle of the image, as columns: each bin is the
    # mean of the columns it covers (a point sample would alias fine texture).
    azimuth = np.arange(_BINS_PER_IMAGE + 1) / _BINS_PER_IMAGE * step - step / 2.0
    edges_px = np.clip(np.rint(width / 2.0 + focal_px * np.tan(azimuth)), 0, width).astype(int)
    rows = np.linspace(0, height, _BANDS + 1).astype(int)
    starts = np.minimum(rows[:-1], height - 1)  # a sweep under _BANDS rows high shares rows
    ends = np.maximum(rows[1:], starts + 1)
    profiles = np.stack(
        [images[:, a:b, :].mean(axis=1) for a, b in zip(starts, ends, strict=True)]
    )  # (B, N, W): each band's column means
    summed = np.concatenate(
        (np.zeros((_BANDS, n, 1)), np.cumsum(profiles, axis=2, dtype=np.float64)), axis=2
    )
    widths = np.maximum(np.diff(edges_px), 1)
    binned = (summed[:, :, edges_px[1:]] - summed[:, :, edges_px[:-1]]) / widths
    panorama = binned.reshape(_BANDS, -1)  # (B, N * bins): a turn is a cyclic shift
    spectra = np.fft.rfft(panorama, axis=1)[:, 1 : _FREQUENCIES + 1]  # (B, K)
    parts = [np.abs(spectra).ravel()]
    for a in range(_BANDS):
        for b in range(a + 1, _BANDS):
            cross = spectra[a] * np.conj(spectra[b])
            parts += [cross.real, cross.imag]
    raw = np.concatenate(parts)
    values = np.sign(raw) * np.log1p(np.abs(raw))
    values -= values.mean()
    norm = float(np.linalg.norm(values))
    descriptor: np.ndarray = (values / norm if norm > 0.0 else values).astype(np.float32)
    return descriptor


class DescriptorIndex:
    """Descriptors of the known junctions, in the order they were added."""

    def __init__(self) -> None:
        self._rows: np.ndarray | None = None
        self._count = 0

    def __len__(self) -> int:
        return self._count

    def add(self, row: np.ndarray) -> None:
        """Append the next junction's descriptor (the rows grow by doubling)."""
        if self._rows is None:
            self._rows = np.empty((16, row.size), dtype=np.float32)
        elif self._count == self._rows.shape[0]:
            grown = np.empty((2 * self._count, row.size), dtype=np.float32)
            grown[: self._count] = self._rows
            self._rows = grown
        self._rows[self._count] = row
        self._count += 1

    def truncate(self, count: int) -> None:
        """Forget every descriptor after the first ``count``."""
        self._count = min(self._count, count)

    def nbytes(self) -> int:
        """Memory the descriptors of the known junctions take."""
        return 0 if self._rows is None else self._count * self._rows.shape[1] * 4

    def nearest(self, query: np.ndarray, k: int, also: Iterable[int] = ()) -> np.ndarray:
        """Indices, ascending, of the ``k`` junctions nearest ``query`` (ties to the
        earliest) together with the known ones of ``also``."""
        if self._rows is None or self._count == 0:
            return np.zeros(0, dtype=np.int64)
        scores = self._rows[: self._count] @ query
        if k < self._count:
            # Exactly the k best, ties to the earliest: order by (-score, index).
            cut = np.partition(-scores, k - 1)[k - 1]
            inside = np.flatnonzero(-scores < cut)
            tied = np.flatnonzero(-scores == cut)[: k - inside.size]
            chosen = np.concatenate((inside, tied))
        else:
            chosen = np.arange(self._count)
        extra = [i for i in also if 0 <= i < self._count]
        return np.unique(np.concatenate((chosen, np.asarray(extra, dtype=np.int64))))
