"""A closer look: the two-view check of the junction the map expects, at full detail.

Sweeps wider than :attr:`TwoViewConfig.detect_width_px` give ORB their images
reduced (400 px to 200 px) and keep 250 keypoints an image
(:func:`localizer.twoview.stored_features`): a third of the cost, and the same
decisions where the robot sweeps a junction from near where it swept it before.
From a spot 10 cm away the near walls change too much for those keypoints: on
``random:17`` seed 7 at 400 px the robot came back to a junction out of a dead end
and stopped 10.4 cm from where it had swept it first; the reduced keypoints gave 86
matches and 23 inliers, one short of :attr:`LocalizerConfig.expected_inliers`, and
the map went wrong.

So when the fit with the junction the map expects (:meth:`Localizer.expected_node`)
falls short, it is made once more on keypoints of the images at the detail given
here (:func:`closer_config`: at 400 px, the images themselves, 400 keypoints each),
with the same bar. The same pair then fits with 44 inliers. Keypoints at full detail
tell junctions apart better, not worse: over that log's 136 pairs of different
junctions (every image against every image), the best fit had 8 inliers instead of
15, and its four pairs of one junction swept 10 cm apart 37 to 40 instead of 17
(docs/simulator.md, ``benchmarks/why_two_view.py``).

Only the expected junction gets the closer look, and only after its fit failed. Its
cost (``python benchmarks/bench_closer_look.py``, one core, CPU time): ORB once more
on each new junction's images, 19 ms at 400 px, and 83 KiB kept a junction (the
check's keypoints: 7 ms, 48.5 KiB); where the look is taken, the decision took 99 ms
against 45 ms without it.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.twoview import (
    StoredFeatures,
    SweepFeatures,
    TwoViewConfig,
    detection_factor,
    stored_features,
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
    """The full-detail keypoints of the known junctions, and of the visit at hand
    (computed only when asked for)."""

    def __init__(self, config: LocalizerConfig) -> None:
        self._on = config.closer_look
        self._base = config.two_view_config
        self._config = closer_config(self._base, config.closer_keypoints_per_image)
        self._known: dict[int, StoredFeatures] = {}
        self._query: tuple[ImageSet, SweepFeatures] | None = None
        #: Closer looks taken so far (fits made at full detail).
        self.taken = 0

    def sharper(self, image_set: ImageSet) -> bool:
        """Whether the closer look sees ``image_set`` in more detail than the check
        does (its images were reduced for the check)."""
        width = int(image_set.images.shape[2])
        return detection_factor(width, self._config) < detection_factor(width, self._base)

    def keep(self, node: int, image_set: ImageSet) -> None:
        """Remember the full-detail keypoints of new junction ``node``'s sweep (with
        ``closer_look`` on)."""
        if self._on and self.sharper(image_set):
            self._known[node] = stored_features(image_set, self._config)

    def known(self, node: int) -> SweepFeatures | None:
        """Junction ``node``'s full-detail keypoints (``None``: none kept)."""
        stored = self._known.get(node)
        return None if stored is None else stored.features()

    def query(self, image_set: ImageSet) -> SweepFeatures | None:
        """The full-detail keypoints of the visit's ``image_set`` (once per set)."""
        if not self.sharper(image_set):
            return None
        if self._query is None or self._query[0] is not image_set:
            self._query = (image_set, stored_features(image_set, self._config).features())
        return self._query[1]

    def pair(self, node: int, image_set: ImageSet) -> tuple[SweepFeatures, SweepFeatures] | None:
        """The full-detail keypoints of the visit's ``image_set`` and of junction
        ``node``; ``None`` when either has none (``node``'s were not kept, or the
        visit's images are not reduced for the check)."""
        known = self.known(node)
        query = None if known is None else self.query(image_set)
        if query is None or known is None:
            return None
        self.taken += 1
        return query, known

    @property
    def nbytes(self) -> int:
        """Memory held by the known junctions' keypoints."""
        return sum(s.nbytes for s in self._known.values())
