"""Junction recognition: the paper's Algorithms 1 (decide) and 3 (active vision).

:class:`Localizer` keeps the image set of every known junction and the topological
map. For each junction visit it matches the visit's image set with every known one
(:class:`localizer.fastmatch.FastMatcher`), and when the best similarity is below
the threshold it asks its caller for probe image sets, in the paper's order, until
one improves the best similarity. Then it decides known or new and updates the map.

Active vision is a protocol, not motion: the caller passes a :class:`ProbeSource`
that turns a :class:`ProbeRequest` into an image set (the simulator moves the robot
and sweeps; a replay looks the sweep up in the log) or answers ``None`` when it
cannot, which the decision records.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field, replace
from typing import Protocol

from pipemap.errors import LocalizerError
from pipemap.localizer.fastmatch import FastConfig, FastMatcher, PreparedSet
from pipemap.localizer.illumination import IlluminationConfig, normalised
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.presets import PAPER_THRESHOLD
from pipemap.localizer.similarity import SetMatch
from pipemap.localizer.topomap import TopoMap
from pipemap.localizer.twoview import (
    StoredFeatures,
    SweepFeatures,
    TwoViewConfig,
    TwoViewFit,
    fit_two_view,
    stored_features,
)

__all__ = [
    "DEFAULT_THRESHOLD",
    "PAPER",
    "Decision",
    "Localizer",
    "LocalizerConfig",
    "ProbeKind",
    "ProbeOutcome",
    "ProbeRequest",
    "ProbeSource",
    "best_candidate",
    "probe_plan",
]

#: The localizer's default threshold: the paper's (see :mod:`.presets`).
DEFAULT_THRESHOLD = PAPER_THRESHOLD


class ProbeKind(enum.Enum):
    """The paper's active-vision moves, in the order they are tried."""

    ROTATE = "rotate"
    FORWARD = "forward"
    BACK = "back"
    LEFT = "left"
    RIGHT = "right"


@dataclass(frozen=True)
class ProbeRequest:
    """One active-vision move, relative to the pose of the original sweep.

    ``yaw_rad`` turns the robot in place (positive counter-clockwise seen from
    above); ``forward_m`` and ``left_m`` move it in its own frame.
    """

    kind: ProbeKind
    yaw_rad: float = 0.0
    forward_m: float = 0.0
    left_m: float = 0.0


class ProbeSource(Protocol):
    """Supplies the image set seen after a probe move, or ``None`` if it cannot."""

    def probe(self, request: ProbeRequest) -> ImageSet | None:
        """Perform (or look up) ``request`` and return the sweep taken after it."""
        ...


@dataclass(frozen=True)
class ProbeOutcome:
    """What one probe gave: its best similarity, or ``None`` if it was not supplied."""

    request: ProbeRequest
    similarity: float | None
    improved: bool


@dataclass(frozen=True)
class LocalizerConfig:
    """Settings of the localizer; the defaults are the paper's except three rules of
    pipemap's own: ``distinct_consecutive``, ``two_view`` and ``verify``. :data:`PAPER`
    turns all three off."""

    threshold: float = DEFAULT_THRESHOLD
    active_vision: bool = True
    probe_distance_m: float = 0.03
    fast: FastConfig = field(default_factory=FastConfig)
    #: A visit cannot be the junction of the visit just before it. Between two sweeps
    #: the robot drives along a pipe, and a pipe joins two different junctions: a node
    #: is wherever the pipe does more than go straight, so a pipe that returned to its
    #: own junction would pass a corner node first. Not in the paper, which compares
    #: with every known junction; turn it off for image sets that are not a traversal
    #: (several sweeps of one junction in a row).
    distinct_consecutive: bool = True
    #: Estimate the rotation of a recognised junction by two-view geometry (see
    #: :mod:`localizer.twoview`), and report it as the decision's rotation. Not in the
    #: paper. It assumes the camera turns about its own centre, as pipemap's robot's
    #: does; a robot standing off level (the paper's image sets) is allowed for.
    two_view: bool = True
    two_view_config: TwoViewConfig = field(default_factory=TwoViewConfig)
    #: Decide known or new by two-view geometry (needs ``two_view``): the visit is the
    #: first of the ``verify_candidates`` best junctions (refined ones first) whose
    #: keypoints fit one motion with this one's with at least ``verify_inliers``
    #: inliers, and new if none does. The threshold then only calls for probes (and
    #: decides sweeps with too few keypoints to check). Not in
    #: the paper: over 61 logs, same-junction pairs fit with 179 inliers or more at
    #: 400 px (59 at 96 px), different ones with 13 at most (37 at 96 px), measured
    #: with every image pair matched (before ``TwoViewConfig.overlap_only``, which
    #: raises the counts of both; not re-measured over those logs).
    verify: bool = True
    verify_inliers: int = 48
    verify_candidates: int = 4
    #: A sweep with fewer keypoints is decided by the threshold (a 32 px sweep has
    #: about 25, a 96 px one about 2000).
    verify_min_keypoints: int = 200
    #: The sweeps are lit by the robot's own lamp: divide every image by its own
    #: illumination estimate (:mod:`localizer.illumination`) before matching, and
    #: when the two-view fit at the NCC's rotation fails, fit again at any rotation
    #: (under a lamp the NCC often turns a cross by a quarter or a half). ``None``:
    #: as the camera says (:meth:`for_camera`; a replay asks the log's simulator
    #: settings); unset, evenly lit, as the paper's image sets are. Not in the paper.
    lamp: bool | None = None
    illumination: IlluminationConfig = field(default_factory=IlluminationConfig)

    def for_camera(self, lamp_lit: bool) -> LocalizerConfig:
        """These settings for a camera that is (or is not) lit by a lamp, unless
        ``lamp`` was set explicitly."""
        return self if self.lamp is not None else replace(self, lamp=lamp_lit)

    def __post_init__(self) -> None:
        if not -1.0 <= self.threshold <= 1.0:
            raise LocalizerError(f"threshold must be in [-1, 1], got {self.threshold}")
        if not (self.probe_distance_m >= 0.0 and math.isfinite(self.probe_distance_m)):
            raise LocalizerError(f"probe distance must be >= 0 m, got {self.probe_distance_m}")
        if self.verify and not self.two_view:
            raise LocalizerError("verify decides by the two-view fit: it needs two_view")
        if self.verify_inliers < 1 or self.verify_candidates < 1:
            raise LocalizerError("verify_inliers and verify_candidates must be >= 1")


#: The paper's rules: every known junction competes (the previous visit's included),
#: the threshold decides, and the rotation is the NCC peak shift's.
PAPER = LocalizerConfig(distinct_consecutive=False, two_view=False, verify=False)


@dataclass(frozen=True)
class Decision:
    """The localizer's answer for one junction visit.

    ``node`` is the map node of the visit; ``known`` says whether it was recognised.
    ``candidate`` is the best-matching known node (``None`` on the first visit) and
    ``match`` its match, from the probe sweep if a probe improved it. ``similarity``
    is that match's similarity (0.0 with no candidate), ``margin`` the best minus
    the second-best similarity among the refined candidates (``None`` with fewer
    than two).
    ``missing_probes`` counts requested probes the caller could not supply.
    ``two_view`` is the two-view fit with the recognised junction (known visits
    only, with ``LocalizerConfig.two_view``; ``None`` if too few keypoints fit).
    """

    node: int
    known: bool
    candidate: int | None
    similarity: float
    margin: float | None
    match: SetMatch | None
    probes: tuple[ProbeOutcome, ...] = ()
    two_view: TwoViewFit | None = None

    @property
    def rotation_rad(self) -> float | None:
        """The best rotation estimate from this visit's heading to the candidate's:
        the two-view one if there is one, else the paper's (``None`` without a match)."""
        if self.two_view is not None:
            return self.two_view.rotation_rad
        return None if self.match is None else self.match.rotation_rad

    @property
    def missing_probes(self) -> int:
        """Number of probes requested but not supplied."""
        return sum(1 for p in self.probes if p.similarity is None)


def best_candidate(
    matches: list[SetMatch], exclude: int | None = None
) -> tuple[int | None, float, float | None]:
    """Algorithm 1's choice: the best candidate, its similarity, the margin to the second.

    Only refined matches compete when there are any: a screening score is biased
    (it ranks, it does not measure) and must not decide. Ties go to the earliest
    known junction. The visit is known when the similarity reaches the threshold.
    The junction ``exclude`` (if any) never competes.
    """
    allowed = [i for i in range(len(matches)) if i != exclude]
    pool = [i for i in allowed if matches[i].refined] or allowed
    if not pool:
        return None, 0.0, None
    best = max(pool, key=lambda i: (matches[i].similarity, -i))
    margin = None
    if len(pool) > 1:
        margin = matches[best].similarity - max(matches[i].similarity for i in pool if i != best)
    return best, matches[best].similarity, margin


def probe_plan(estimated_rotation_rad: float, distance_m: float) -> tuple[ProbeRequest, ...]:
    """The paper's probe order: rotate by the estimated relative angle, then move.

    The rotation turns the robot so that its sweep lines up with the candidate's
    (the estimate is the candidate's sweep relative to this one).
    """
    return (
        ProbeRequest(ProbeKind.ROTATE, yaw_rad=estimated_rotation_rad),
        ProbeRequest(ProbeKind.FORWARD, forward_m=distance_m),
        ProbeRequest(ProbeKind.BACK, forward_m=-distance_m),
        ProbeRequest(ProbeKind.LEFT, left_m=distance_m),
        ProbeRequest(ProbeKind.RIGHT, left_m=-distance_m),
    )


class Localizer:
    """Known/new decisions over a growing database of junctions, and the map."""

    def __init__(self, config: LocalizerConfig | None = None) -> None:
        self.config = config if config is not None else LocalizerConfig()
        self._matcher = FastMatcher(self.config.fast)
        #: Keypoints by node (with ``config.two_view``), computed once per sweep, kept compact.
        self._features: list[StoredFeatures] = []
        self.map = TopoMap()

    @property
    def known_count(self) -> int:
        """Number of junctions known so far."""
        return len(self._matcher)

    def compare(self, query: ImageSet) -> list[SetMatch]:
        """The query's match with every known junction, in node order."""
        return self._matcher.match(self._matcher.prepare(query))

    def _excluded(self) -> int | None:
        if self.config.distinct_consecutive:
            return self.map.previous
        return None

    def _best(
        self, prepared: PreparedSet
    ) -> tuple[list[SetMatch], int | None, float, float | None]:
        exclude = self._excluded()
        matches = self._matcher.match(prepared, exclude)
        best, sim, margin = best_candidate(matches, exclude)
        return matches, best, sim, margin

    def localize(self, query: ImageSet, probes: ProbeSource | None = None) -> Decision:
        """Decide known or new for one junction visit, and add the visit to the map.

        The image set stored for a new junction is the visit's own sweep (not a
        probe's), so every junction is remembered as seen from its centre.
        """
        query = self._lit(query)
        prepared = self._matcher.prepare(query)
        matches, best, sim, margin = self._best(prepared)
        match = matches[best] if best is not None else None
        # The sweep that gave ``match``, its matches (as computed, not turned), its turn.
        matched, matched_all, turn = query, matches, 0.0
        outcomes: list[ProbeOutcome] = []
        weak = best is not None and sim < self.config.threshold
        if weak and self.config.active_vision and probes is not None and match is not None:
            for request in probe_plan(match.rotation_pinhole_rad, self.config.probe_distance_m):
                probe_set = probes.probe(request)
                if probe_set is None:
                    outcomes.append(ProbeOutcome(request, None, False))
                    continue
                query.check_comparable(probe_set)
                probe_set = self._lit(probe_set)
                p_matches, p_best, p_sim, p_margin = self._best(self._matcher.prepare(probe_set))
                improved = p_sim > sim
                outcomes.append(ProbeOutcome(request, p_sim, improved))
                if improved:
                    best, sim, margin = p_best, p_sim, p_margin
                    match = p_matches[p_best] if p_best is not None else None
                    matched, matched_all, turn = probe_set, p_matches, request.yaw_rad
                    if match is not None:
                        # The probe's rotation is from the turned heading; report it
                        # from the visit's own, as every other decision is.
                        match = match.turned(request.yaw_rad)
                    break
        fit = None
        features = None
        stored = None
        if self.config.two_view:
            stored = stored_features(matched, self.config.two_view_config)
            features = stored.features()
        if features is not None and self.config.verify and self._checkable(features):
            verified = self._verified(features, matched_all)
            known = verified is not None
            if verified is not None:
                best, raw_fit = verified
                match = matched_all[best].turned(turn)
                sim = match.similarity
                fit = raw_fit.turned(turn)
        else:
            known = best is not None and sim >= self.config.threshold
            if known and features is not None:
                assert best is not None
                guess = matched_all[best].rotation_rad
                config = self.config.two_view_config
                raw = fit_two_view(features, self._features[best].features(), config, guess)
                fit = None if raw is None else raw.turned(turn)
        if known:
            assert best is not None
            node = best
        else:
            node = self._matcher.add(prepared)
            if stored is not None:
                if matched is not query:  # a probe's: remember the visit's own sweep
                    stored = stored_features(query, self.config.two_view_config)
                self._features.append(stored)
        self.map.visit(node)
        return Decision(
            node=node,
            known=known,
            candidate=best,
            similarity=sim,
            margin=margin,
            match=match,
            probes=tuple(outcomes),
            two_view=fit,
        )

    def _lit(self, image_set: ImageSet) -> ImageSet:
        """The set as the matcher sees it: normalised if lamp-lit."""
        return normalised(image_set, self.config.illumination) if self.config.lamp else image_set

    def _checkable(self, features: SweepFeatures) -> bool:
        """Enough keypoints for the two-view check to decide; with fewer (images of a
        few dozen pixels), the threshold decides, as in the paper."""
        return len(features) >= self.config.verify_min_keypoints

    def _verified(
        self, features: SweepFeatures, matches: list[SetMatch]
    ) -> tuple[int, TwoViewFit] | None:
        """The first of the best junctions (refined ones first, each by similarity)
        that the sweep's keypoints fit, with that fit (unturned); ``None`` if none does."""
        exclude = self._excluded()
        # Refined junctions first, then screened ones: the two scores differ in scale.
        allowed = [i for i in range(len(matches)) if i != exclude]
        ranked = sorted(allowed, key=lambda i: (not matches[i].refined, -matches[i].similarity, i))
        # A fit with fewer inliers would not count: let it stop as soon as it knows
        # (so only the junction that fits pays for the tilted refinement).
        config = replace(
            self.config.two_view_config,
            min_inliers=max(self.config.two_view_config.min_inliers, self.config.verify_inliers),
        )
        for i in ranked[: self.config.verify_candidates]:
            known = self._features[i].features()
            fit = fit_two_view(features, known, config, matches[i].rotation_rad)
            if self.config.lamp and (fit is None or fit.inliers < self.config.verify_inliers):
                fit = fit_two_view(features, known, config, None)
            if fit is not None and fit.inliers >= self.config.verify_inliers:
                return i, fit
        return None
