"""The two-view check of one candidate junction, at the rotations its pipes allow.

The NCC's rotation guides the fit (:func:`localizer.twoview.fit_two_view`), and the
NCC can be wrong by a quarter or a half turn: under the robot's lamp it often is,
and at a junction that looks the same turned (a cross) the images of the wrong turn
still fit, with fewer keypoints. The range scan says more: the visit's pipes must
line up with the candidate's ports, which leaves a few rotations only
(:func:`localizer.ports.port_rotations`: one at a T or a dead end, four at a
cross). So the candidate is also fitted at each of them, and the rotation its
keypoints fit best is kept:

- the fit at the NCC's rotation failed: each allowed rotation is tried (what was
  once a fit at any rotation, under the lamp only);
- it passed: each other allowed rotation must fit more keypoints to replace it (so
  a wrong turn stops at its first gate), of as many of the candidate's keypoints
  as the passing fit matched (a fit may stop after the first stages,
  :attr:`localizer.twoview.TwoViewConfig.accept_share`);
- no rotation is allowed (the pipes cannot line up): none is tried; the port check
  passes the junction over anyway.

Without ports to go by (image folders, no exits), a failed fit is tried again at
any rotation under the lamp, as before.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

from pipemap.localizer.keymatch import MatchCache
from pipemap.localizer.twoview import SweepFeatures, TwoViewConfig, TwoViewFit, fit_two_view

__all__ = ["candidate_fit"]


def _apart(a_rad: float, b_rad: float) -> float:
    return abs(math.remainder(a_rad - b_rad, 2.0 * math.pi))


def _refits(
    guess_rad: float, rotations: tuple[float, ...] | None, any_rotation: bool, config: TwoViewConfig
) -> bool:
    """Whether a second fit of the pair may follow the guided one."""
    if rotations is None:
        return any_rotation
    return any(_apart(guess_rad, r) > config.search_rad / 2.0 for r in rotations)


def candidate_fit(
    query: SweepFeatures,
    known: SweepFeatures,
    guess_rad: float,
    needed: int,
    config: TwoViewConfig,
    rotations: tuple[float, ...] | None,
    agrees: Callable[[TwoViewFit], bool],
    any_rotation: bool,
    tolerance_rad: float,
    cache: MatchCache | None = None,
    closer: Callable[[], tuple[SweepFeatures, SweepFeatures] | None] | None = None,
) -> TwoViewFit | None:
    """The fit of the visit's sweep ``query`` with a candidate's ``known`` sweep: at
    least ``needed`` inliers, or ``None``.

    ``rotations`` are the rotations the candidate's ports allow (in the query's
    frame; ``None``: unknown), ``agrees`` says whether a fit's rotation lines the
    exits up with the ports, ``tolerance_rad`` how far a fit's rotation may lie
    from an allowed one. A fit whose rotation ``agrees`` is preferred; one that does
    not is returned only when none does (for the caller to pass the candidate over,
    and say why). ``any_rotation``: without ``rotations``, fit again without a
    guess when the guided fit fails. ``cache`` shares the keypoint distances among
    the fits. ``closer``, if given, gives more keypoints of the two sweeps
    (:mod:`localizer.closer`): where no fit reaches ``needed``, the candidate is fitted
    once more on those (when it gives them).
    """

    def fit_pair(
        query: SweepFeatures, known: SweepFeatures, cache: MatchCache | None
    ) -> TwoViewFit | None:
        if (
            cache is None
            and query.image is not None
            and _refits(guess_rad, rotations, any_rotation, config)
        ):
            cache = MatchCache(query)

        def fit_at(guess: float | None, bar: int, around_peak: bool = True) -> TwoViewFit | None:
            asked = replace(
                config, min_inliers=max(config.min_inliers, bar), around_peak=around_peak
            )
            return fit_two_view(query, known, asked, guess, cache=cache)

        def beats(rotation: float, best: TwoViewFit) -> TwoViewFit | None:
            # On as many of the known keypoints as the fit at hand matched: counts of
            # the same stages compare; the rival does not stop early on its own.
            limit = 0 if best.stages is None else best.stages
            asked = replace(
                config,
                min_inliers=max(config.min_inliers, best.inliers + 1),
                around_peak=False,
                accept_share=0.0,
                stage_limit=limit,
            )
            return fit_two_view(query, known, asked, rotation, cache=cache)

        first = fit_at(guess_rad, needed)
        if rotations is None:
            if first is None and any_rotation:
                first = fit_at(None, needed)
            return first
        best = first if first is not None and agrees(first) else None
        for rotation in rotations:
            if best is not None and _apart(best.rotation_rad, rotation) <= tolerance_rad:
                continue  # the fit at hand is this rotation's
            if first is None and _apart(guess_rad, rotation) <= config.search_rad / 2.0:
                continue  # the failed fit searched here already
            other = fit_at(rotation, needed, False) if best is None else beats(rotation, best)
            if other is None or not agrees(other):
                continue
            # Only another turn replaces a fit (its matches, found in other images, may
            # fit the same turn with more keypoints: that is no news).
            if best is None or _apart(other.rotation_rad, best.rotation_rad) > tolerance_rad:
                best = other
        return best if best is not None else first

    best = fit_pair(query, known, cache)
    pair = None if closer is None or (best is not None and best.inliers >= needed) else closer()
    return best if pair is None else fit_pair(pair[0], pair[1], None)
