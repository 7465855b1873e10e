"""What the localizer answers for a junction visit, and the probes it may ask for.

A :class:`Decision` per visit; the paper's active-vision moves (:class:`ProbeKind`,
in the order :func:`probe_plan` gives them), asked of a :class:`ProbeSource` (the
simulator moves the robot, a replay looks the sweep up in the log); and Algorithm
1's choice of the best candidate (:func:`best_candidate`).
"""

from __future__ import annotations

import enum
import heapq
import itertools
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from pipemap.localizer.fastmatch import UNSCREENED, Shortlisted
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.similarity import SetMatch
from pipemap.localizer.twoview import TwoViewFit

if TYPE_CHECKING:
    from pipemap.localizer.config import LocalizerConfig

__all__ = [
    "Decision",
    "ProbeKind",
    "ProbeOutcome",
    "ProbeRequest",
    "ProbeSource",
    "best_candidate",
    "alike_candidates",
    "threshold_candidates",
    "check_order",
    "probe_plan",
]


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

    With the visit's exits given: ``exits_rad`` are they, ``exit_ports`` the port of
    the node that each is (``None`` without exits), ``arrival_port`` the port the
    robot came in by (the exit behind it; ``None`` on a traversal's first visit),
    ``port_residual_rad`` the largest misfit of a known visit's exits with its
    ports, and ``rejected`` the candidates the images matched but whose ports did
    not, each with the reason.

    ``alike`` are the other known junctions that a known visit could as well have
    been: they passed every check the recognised one passed before its fit (ports,
    odometry) and matched within ``LocalizerConfig.alike_margin`` of its similarity,
    and the map did not expect the recognised one. The decision is then the best
    ranked of equals, not told apart by anything: it says so rather than pass for sure.

    ``hypotheses`` is the number of maps alive after this visit
    (:mod:`localizer.hypotheses`); ``deferred`` the other junctions this visit may
    still be (it is open: the maps disagree, ``node`` is the heaviest map's); and
    ``settled`` the earlier open visits this one decided, each as ``(visit index,
    node)`` (visit index in the map's visit order).
    """

    node: int
    known: bool
    candidate: int | None
    similarity: float
    margin: float | None
    match: SetMatch | None
    probes: tuple[ProbeOutcome, ...] = ()
    two_view: TwoViewFit | None = None
    exits_rad: tuple[float, ...] | None = None
    exit_ports: tuple[int, ...] | None = None
    arrival_port: int | None = None
    port_residual_rad: float | None = None
    rejected: tuple[tuple[int, str], ...] = ()
    alike: tuple[int, ...] = ()
    hypotheses: int = 1
    deferred: tuple[int, ...] = ()
    settled: tuple[tuple[int, int], ...] = ()

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

    def describe(self) -> str:
        """The decision in one line, as ``pipemap -v`` prints it: the junction, new
        or known, the best candidate's similarity and margin, the two-view fit, the
        probes taken and the candidates whose ports did not line up."""
        parts = [f"junction {self.node} {'known' if self.known else 'new'}"]
        if self.candidate is not None:
            margin = "" if self.margin is None else f", margin {self.margin:.3f}"
            parts.append(f"best candidate {self.candidate} at {self.similarity:.3f}{margin}")
        if self.two_view is not None:
            fit = self.two_view
            parts.append(f"two-view {fit.inliers} inliers, turn {fit.rotation_rad:+.4f} rad")
        if self.probes:
            answered = len(self.probes) - self.missing_probes
            parts.append(f"{len(self.probes)} probes asked, {answered} answered")
        for node, why in self.rejected:
            parts.append(f"{node} rejected: {why}")
        if self.alike:
            parts.append(f"as alike: {', '.join(map(str, self.alike))} (nothing told them apart)")
        if self.deferred:
            parts.append(
                f"deferred: may be {', '.join(map(str, self.deferred))} "
                f"({self.hypotheses} hypotheses alive)"
            )
        for visit, node in self.settled:
            parts.append(f"visit {visit} settled as junction {node}")
        return "; ".join(parts)


def best_candidate(
    matches: list[SetMatch], exclude: int | None = None
) -> tuple[int | None, float, float | None]:
    """Algorithm 1's choice: the best candidate, its similarity, the margin to the second.

    Only refined matches compete when there are any: a screening score is biased
    (it ranks, it does not measure) and must not decide. Ties go to the earliest
    known junction. The visit is known when the similarity reaches the threshold.
    The junction ``exclude`` (if any) never competes.
    """
    pool = [i for i in _screened(matches) if matches[i].refined and i != exclude] or [
        i for i in range(len(matches)) if i != exclude
    ]
    if not pool:
        return None, 0.0, None
    best = max(pool, key=lambda i: (matches[i].similarity, -i))
    margin = None
    if len(pool) > 1:
        margin = matches[best].similarity - max(matches[i].similarity for i in pool if i != best)
    return best, matches[best].similarity, margin


def _screened(matches: list[SetMatch]) -> list[int]:
    """The junctions not :data:`UNSCREENED` (the only ones a screen refines), from the
    matcher's list when it names them (:class:`Shortlisted`)."""
    if isinstance(matches, Shortlisted):
        return matches.screened
    return [i for i, m in enumerate(matches) if m is not UNSCREENED]


def check_order(
    matches: list[SetMatch], allowed: Callable[[int], bool], count: int
) -> tuple[list[int], list[int]]:
    """The first ``count`` junctions ``allowed`` in the order the two-view check tries
    them (refined first, then by similarity, then by node), and the screened ones.

    Those the index left out (all :data:`UNSCREENED`, alike) follow in node order and
    are looked at only when the screened ones leave room: the order of sorting every
    known junction, without a pass over each of them."""
    screened = _screened(matches)
    unscreened = (i for i in range(len(matches)) if matches[i] is UNSCREENED)

    def rank(i: int) -> tuple[bool, float, int]:
        return (not matches[i].refined, -matches[i].similarity, i)

    merged = heapq.merge(sorted(screened, key=rank), unscreened, key=rank)
    return list(itertools.islice(filter(allowed, merged), count)), screened


def threshold_candidates(
    matches: list[SetMatch],
    best: int | None,
    best_sim: float,
    config: LocalizerConfig,
    exclude: int | None,
    near: Callable[[int], bool],
) -> list[int]:
    """The paper's decision, with room for the port and odometry checks: the best
    candidate if its similarity reaches the threshold and the dead reckoning allows it
    (``near``), then (only when either check is on) the other candidates of its pool
    that reach the threshold and that the dead reckoning allows, best first, up to
    ``config.verify_candidates`` in all (``exclude``: the junction just left)."""
    if best is None or best_sim < config.threshold:
        return []
    if not config.port_check and not config.odometry_check:
        return [best]
    # The odometry check acts here as among the two-view candidates: a junction
    # farther than the dead reckoning's drift allows is not the visit's.
    allowed = [i for i in range(len(matches)) if i != exclude and near(i)]
    pool = [i for i in allowed if matches[i].refined] or allowed
    others = sorted(
        (i for i in pool if i != best and matches[i].similarity >= config.threshold),
        key=lambda i: (-matches[i].similarity, i),
    )
    first = [best] if near(best) else []
    return [*first, *others][: config.verify_candidates]


def alike_candidates(
    node: int,
    expected: int | None,
    allowed: Callable[[int], bool],
    matches: list[SetMatch],
    screened: list[int],
    margin: float,
) -> tuple[int, ...]:
    """The other allowed candidates as good as ``node`` by all but its fit: as
    refined, within ``margin`` of its similarity; none when the map expected it.
    ``screened`` are the junctions not :data:`UNSCREENED` (the others are looked at
    only when that score is within the margin)."""
    if node == expected:
        return ()
    sim = matches[node].similarity
    near = UNSCREENED.refined == matches[node].refined and (
        abs(UNSCREENED.similarity - sim) <= margin
    )
    pool = range(len(matches)) if near else screened
    return tuple(
        j
        for j in pool
        if j != node
        and matches[j].refined == matches[node].refined
        and abs(matches[j].similarity - sim) <= margin
        and allowed(j)
    )


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
