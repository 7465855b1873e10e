"""The two-view fits of one visit, each computed once.

Where a visit may be one of several junctions of a look (competing maps,
:mod:`localizer.hypotheses`), its sweep can be fitted to the same known junction
more than once: the choice among the candidates (``Localizer._verified``) fits a
junction and passes it over for its ports or for the pipe end the robot came in
by, and the branch "new, or a look-alike seen before" (:mod:`localizer.branching`)
then asks again whether that junction's keypoints fit (on ``grid:4x4`` seed 2 at
``--alike 1 --odometry-drift 10``, 2 of the 33 fits of a replay). A fit depends on
the visit's sweep, the known junction's keypoints, the rotation guessed, the
inliers asked, the visit's exits and turn, and the junction's ports in the map it
is checked against (the rotations they allow, and the port check of each fit).
:class:`VisitFits` keeps each fit under all of these and gives it back when the
very same is asked again, so the fit, and every decision, are those of fitting
anew.

Nothing is kept past the visit: a new sweep drops it all. A junction id is looked
up with the keypoints stored under it (competing maps draw ids from one pool, and a
fit of another junction's keypoints under the same id is never given back), and
with its ports in the map that asks.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import TYPE_CHECKING

from pipemap.localizer.verify import candidate_fit

if TYPE_CHECKING:
    from pipemap.localizer.imageset import ImageSet
    from pipemap.localizer.localizer import Localizer
    from pipemap.localizer.twoview import StoredFeatures, SweepFeatures, TwoViewFit

__all__ = ["VisitFits", "fit_once"]


class VisitFits:
    """The two-view fits of one visit's sweep (see the module)."""

    def __init__(self) -> None:
        self._sweep: SweepFeatures | None = None
        #: (node, its stored keypoints, key) -> the fit.
        self._fits: dict[tuple[Hashable, ...], TwoViewFit | None] = {}
        #: The stored keypoints of each node fitted (held: their ids stay theirs).
        self._stored: list[StoredFeatures] = []
        #: Fits computed, and fits given back without computing, since the last visit.
        self.computed = 0
        self.reused = 0

    def start(self, sweep: SweepFeatures | None) -> None:
        """A new visit whose sweep's keypoints are ``sweep``: forget every fit."""
        self._sweep = sweep
        self._fits.clear()
        self._stored.clear()
        self.computed = self.reused = 0

    def fit(
        self,
        sweep: SweepFeatures,
        node: int,
        stored: StoredFeatures,
        key: tuple[Hashable, ...],
        compute: Callable[[], TwoViewFit | None],
    ) -> TwoViewFit | None:
        """The fit of ``sweep`` with known junction ``node`` (its keypoints
        ``stored``) under ``key`` (everything else the fit depends on: guess, inliers
        asked, exits, turn, the junction's ports): the one an earlier call of this
        visit computed for the very same, or ``compute()``."""
        if sweep is not self._sweep:
            self.start(sweep)
        full = (node, id(stored), *key)
        if full in self._fits:
            self.reused += 1
            return self._fits[full]
        fit = compute()
        self.computed += 1
        self._fits[full] = fit
        self._stored.append(stored)
        return fit


def fit_once(
    loc: Localizer,
    node: int,
    features: SweepFeatures,
    guess_rad: float,
    needed: int,
    exits: tuple[float, ...] | None,
    turn: float,
    closer: ImageSet | None = None,
) -> TwoViewFit | None:
    """``Localizer._fit``: the two-view fit of the visit's sweep ``features`` with
    known junction ``node`` (unturned), with at least ``needed`` inliers, at the
    NCC's rotation ``guess_rad`` or another the ports allow, or on more keypoints of
    the visit's ``closer`` image set (:func:`localizer.verify.candidate_fit`,
    :mod:`localizer.closer`), through the localizer's :class:`VisitFits`. The key
    holds every argument and the junction's ports in the localizer's map, which the
    rotations allowed and the port check read."""
    config = loc.config
    rotations = loc._allowed_rotations(node, exits, turn)
    key = (guess_rad, needed, exits, turn, loc.map.ports(node), rotations, id(closer))
    stored = loc._features[node]
    return loc._fits.fit(
        features,
        node,
        stored,
        key,
        lambda: candidate_fit(
            features,
            stored.features(),
            guess_rad,
            needed,
            config.two_view_config,
            rotations,
            lambda fit: loc._agrees(node, exits, fit.turned(turn).rotation_rad),
            bool(config.lamp),
            config.port_tolerance_rad,
            closer=None if closer is None else lambda: loc._closer.pair(node, closer),
        ),
    )
