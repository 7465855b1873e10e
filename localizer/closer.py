"""A closer look: the two-view check of the junction the map expects, at full detail.

Sweeps wider than :attr:`TwoViewConfig.detect_width_px` give ORB their images
reduced (400 px to 200 px), and the check keeps 250 keypoints an image of them
(:func:`localizer.twoview.stored_features`): a third of the cost, and the same
decisions where the robot sweeps a junction from near where it swept it before. From
a spot 10 cm away the near walls change too much for those keypoints. On
``random:17`` seed 7 at 400 px the robot came back to a junction out of a dead end
and stopped 10.4 cm from where it had swept it first; the fit had 23 inliers where
the junction the map expects needs 24 (:attr:`LocalizerConfig.expected_inliers`),
and the map went wrong.

So when the fit with the junction the map expects (:meth:`Localizer.expected_node`)
falls short on reduced images, it is made once more on keypoints of the images at
their own size (up to 400 px; 400 an image), with the same bar: the same return fits
with 44 inliers. Keypoints at full detail keep junctions apart better than the
check's: over that log's 136 pairs of different junctions, at 12 guessed rotations
and none, the most inliers were 11 against the check's 15
(``benchmarks/two_view_pairs.py``, docs/localizer.md). More keypoints of the reduced
images (800 an image, as a 200 px sweep has) fitted the return as well, and one 12.6
cm off that this does not (32 inliers against 20), but gave different junctions up to
25: no margin below 24.

Only the expected junction gets the closer look, and only after its fit failed; a
sweep the check sees whole (200 px and less) gets none. So its keypoints are found only
then: a new junction keeps the 8-bit images ORB would see
(:attr:`LocalizerConfig.closer_keeps_images`), and the keypoints of a junction looked
at closer replace them. Keeping the keypoints instead costs a third of the memory
and ORB's time at every new junction. Its cost
(``python benchmarks/bench_closer_look.py``, one core, CPU time): see docs/localizer.md.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.twoview import (
    StoredFeatures,
    SweepFeatures,
    TwoViewConfig,
    detected,
    detection_factor,
    orb_input,
)

if TYPE_CHECKING:
    from pipemap.localizer.config import LocalizerConfig

__all__ = ["CloserLook", "closer_config"]


def closer_config(config: TwoViewConfig, keypoints_per_image: int) -> TwoViewConfig:
    """``config`` for the closer look: images reduced to at most twice
    ``detect_width_px`` (a 400 px sweep's own size), ``keypoints_per_image`` each."""
    return replace(
        config,
        detect_width_px=2 * config.detect_width_px,
        keypoints_per_image=keypoints_per_image,
        reduced_keypoints_per_image=keypoints_per_image,
    )


class CloserLook:
    """The closer look's keypoints of the known junctions, and of the visit at hand,
    each found when first asked for."""

    def __init__(self, config: LocalizerConfig) -> None:
        self._base = config.two_view_config
        self._config = closer_config(self._base, config.closer_keypoints_per_image)
        self._lazy = config.closer_keeps_images
        #: By node: its keypoints, or (lazily) what ORB needs to find them.
        self._known: dict[int, StoredFeatures | tuple[StoredFeatures, np.ndarray]] = {}
        self._query: tuple[ImageSet, SweepFeatures] | None = None
        #: Closer looks taken so far (fits made on these keypoints).
        self.taken = 0
        #: Sweeps whose closer-look keypoints were found so far (ORB run on them).
        self.detections = 0

    def sharper(self, image_set: ImageSet) -> bool:
        """Whether the closer look sees ``image_set`` in more detail than the check
        does (its images were reduced for the check); never with 0 keypoints."""
        width = int(image_set.images.shape[2])
        finer = detection_factor(width, self._config) < detection_factor(width, self._base)
        return bool(finer and self._config.keypoints_per_image > 0)

    def _detected(self, frame: StoredFeatures, seen: np.ndarray) -> StoredFeatures:
        self.detections += 1
        return detected(frame, seen, self._config)

    def keep(self, node: int, image_set: ImageSet) -> None:
        """Remember new junction ``node``'s sweep for a closer look: the images ORB
        would see, or (without ``closer_keeps_images``) their keypoints at once."""
        if self.sharper(image_set):
            seen = orb_input(image_set, self._config)
            self._known[node] = seen if self._lazy else self._detected(*seen)

    def known(self, node: int) -> SweepFeatures | None:
        """Junction ``node``'s closer-look keypoints (``None``: none kept), found the
        first time they are asked for; they then replace its images."""
        stored = self._known.get(node)
        if isinstance(stored, tuple):
            stored = self._known[node] = self._detected(*stored)
        return None if stored is None else stored.features()

    def query(self, image_set: ImageSet) -> SweepFeatures | None:
        """The closer look's keypoints of the visit's ``image_set`` (once per set)."""
        if not self.sharper(image_set):
            return None
        if self._query is None or self._query[0] is not image_set:
            found = self._detected(*orb_input(image_set, self._config))
            self._query = (image_set, found.features())
        return self._query[1]

    def pair(self, node: int, image_set: ImageSet) -> tuple[SweepFeatures, SweepFeatures] | None:
        """The closer look's keypoints of the visit's ``image_set`` and of junction
        ``node``; ``None`` when either has none (``node``'s were not kept, or the
        visit's images are not reduced for the check)."""
        if node not in self._known or not self.sharper(image_set):
            return None
        known = self.known(node)
        query = self.query(image_set)
        if query is None or known is None:
            return None
        self.taken += 1
        return query, known

    def forget(self, count: int) -> None:
        """Drop what is kept of the junctions from ``count`` on (a benchmark's undo)."""
        for node in [n for n in self._known if n >= count]:
            del self._known[node]

    @property
    def nbytes(self) -> int:
        """Memory held for the known junctions: keypoints, or images not yet looked at."""
        held = (s if isinstance(s, tuple) else (s,) for s in self._known.values())
        return sum(a.nbytes for kept in held for a in kept)
