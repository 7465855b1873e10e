"""The branches of one visit: which junctions it may be, and whether it may be new.

:meth:`Localizer.localize` decides a visit on the heaviest map; where appearance
cannot decide, these give :class:`localizer.hypotheses.Hypotheses` the other
junctions the visit may be (:func:`alike_branches`), and the branch that it is a
junction not seen before that looks like a known one (:func:`new_branch`).

**The new branch.** A sweep that fits a known junction ``j`` is taken as ``j`` unless
something tells them apart (ports, odometry, the pipe it came by). Where the look
repeats, that is not enough: a junction of the same look may be new. The visit may
be new when all of these hold:

* the robot came by a pipe the map has not driven (a driven pipe says where it leads)
  and the map does not expect ``j`` there;
* the look repeats: another known junction's keypoints fit the sweep too (at least
  ``verify_inliers``, its ports fitting the exits; the best ranked one the odometry
  allows, which then is a branch too, or else the best ranked beyond its reach), or
  the visit names junctions nothing told apart (``Decision.alike``);
* the robot's dead reckoning is not where ``j`` (or the nearest of the known
  junctions the visit may be) was: the new map's likelihood is
  :data:`NEW_LIKELIHOOD` times the probability that the robot is not at ``j`` by the
  odometry's Gaussian (one minus its density ratio at that distance), so at ``j``'s
  own place the branch has no weight, and without dead reckoning there is none;
* that likelihood is not pruned at once against the visit's best branch (below
  ``hypothesis_prune_ratio`` of it).

The new junction then takes the next id of the pool (the matcher's), with the
visit's sweep and its exits as ports; the maps that take the visit as known leave
that id unused and read it as their junction (:attr:`Hypothesis.aliases`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from pipemap.localizer.decision import check_order
from pipemap.localizer.hypotheses import Branch
from pipemap.localizer.ports import PortMatch, clockwise_ports

if TYPE_CHECKING:
    from pipemap.localizer.fastmatch import PreparedSet
    from pipemap.localizer.localizer import Localizer
    from pipemap.localizer.similarity import SetMatch
    from pipemap.localizer.twoview import StoredFeatures, SweepFeatures, TwoViewFit

__all__ = ["NEW_LIKELIHOOD", "REPEAT_CANDIDATES", "alike_branches", "new_branch"]

#: A junction whose look fits a known one's, away from it by odometry, is new this
#: much as often as it is the known one (before the odometry's weight). With the
#: default prune ratio (0.01) the new map outlives its first visit only where the
#: robot is 0.45 sigma of the odometry's Gaussian or more from the known junction;
#: one port conflict (``CONFLICT_LIKELIHOOD``) then drops either map.
NEW_LIKELIHOOD = 0.1
#: How many other known junctions (the best ranked) are fitted to see whether the
#: look repeats.
REPEAT_CANDIDATES = 1

#: The fit a branch was weighed by: the match, the two-view fit and the ports.
Fit = tuple["SetMatch | None", "TwoViewFit | None", "PortMatch | None"]


def alike_branches(
    loc: Localizer,
    alike: tuple[int, ...],
    features: SweepFeatures,
    matched_all: list[SetMatch],
    turn: float,
    exits: tuple[float, ...] | None,
    behind: int | None,
    fits: dict[int, Fit],
) -> list[Branch]:
    """A branch for each junction nothing told apart from the recognised one
    (``alike``) whose keypoints also fit the sweep and whose ports fit the exits;
    their fits go to ``fits``."""
    config = loc.config
    branches = []
    for j in alike:
        if _never_a_branch(loc, j, exits):
            continue  # the fit could only be passed over
        j_fit = loc._fit(j, features, matched_all[j].rotation_rad, 0, exits, turn)
        if j_fit is None or j_fit.inliers < config.verify_inliers:
            continue
        j_ports = loc._ports_of(j, exits, j_fit.turned(turn).rotation_rad)
        if j_ports is not None and not j_ports.agrees and config.port_check:
            continue
        j_exit = None if j_ports is None else j_ports.exit_ports
        j_arrival = None if behind is None or j_exit is None else j_exit[behind]
        if loc._hypotheses.arrival_conflict(j, j_ports, exits):
            continue
        branches.append(Branch(j, j_arrival, j_exit, loc._evidence(j, j_ports)))
        fits[j] = (matched_all[j].turned(turn), j_fit.turned(turn), j_ports)
    return branches


def new_branch(
    loc: Localizer,
    branches: list[Branch],
    alike: tuple[int, ...],
    features: SweepFeatures,
    matched_all: list[SetMatch],
    exits: tuple[float, ...] | None,
    behind: int | None,
    prepared: PreparedSet,
    stored: StoredFeatures | None,
    fits: dict[int, Fit],
) -> tuple[Branch, tuple[float, ...]] | None:
    """The branch that the visit (its sweep ``prepared``, its keypoints ``stored``,
    the recognised junction ``branches[0]``) is a new junction of a known look, and
    its ports; ``None`` where the module's rule does not give one. The new junction
    is added to the matcher's pool when it is given. Where the look repeats, the
    other known junctions of the look that the odometry allows join ``branches``
    (their fits ``fits``), whatever their similarity: it cannot tell them apart."""
    topomap = loc.map
    node = branches[0].node
    if exits is None or stored is None or node == loc.expected_node():
        return None
    previous, last = topomap.previous, topomap.last_visit
    port = None if last is None else last.departure_port
    if previous is not None and port is not None and topomap.edge_at(previous, port) is not None:
        return None  # the robot came by a pipe the map has driven
    # Whether the look repeats counts only where nothing else says so and the new
    # map would live (a branch the look adds only lowers its weight).
    counts = not alike and _new_likelihood(loc, branches) is not None
    repeats = _repeats(loc, branches, features, matched_all, exits, behind, fits, counts, alike)
    log_likelihood = _new_likelihood(loc, branches)
    if log_likelihood is None:
        return None
    # Last, as it costs a fit and adds no branch: whether the look repeats beyond
    # the odometry's reach, where nothing else has said so.
    if not alike and not repeats and not _repeats_far(loc, branches, features, matched_all, exits):
        return None
    new = loc._matcher.add(prepared)
    loc._odometry.remember(new)
    loc._features.append(stored)
    new_ports, exit_ports = clockwise_ports(exits)
    arrival = None if behind is None else exit_ports[behind]
    return Branch(new, arrival, exit_ports, log_likelihood, new=True), new_ports


def _repeats(
    loc: Localizer,
    branches: list[Branch],
    features: SweepFeatures,
    matched_all: list[SetMatch],
    exits: tuple[float, ...] | None,
    behind: int | None,
    fits: dict[int, Fit],
    counts: bool = True,
    alike: tuple[int, ...] = (),
) -> bool:
    """Whether the keypoints of another known junction than the branches' fit the
    sweep, its ports fitting the exits: of the :data:`REPEAT_CANDIDATES` best ranked
    that the odometry allows, each that fits becomes a branch (unless the pipe end
    the robot came in by is taken there). Where none fits, :func:`_repeats_far`
    tries the best ranked beyond the odometry's reach, for the look alone. Unless
    the answer ``counts``, a junction that no fit can make a branch is not fitted
    (and says nothing), nor is one of the look-alikes ``alike``: whether it is a
    branch :func:`alike_branches` asked already (a look-alike that is one is no
    candidate here). The ranking is left as it is: a look-alike passed over takes
    its place among the candidates, so no other junction is fitted in its stead."""
    config, near = loc.config, loc._odometry.near
    other = _other(loc, branches, exits)
    repeats = False
    ranked, _ = check_order(matched_all, lambda i: other(i) and near(i), REPEAT_CANDIDATES)
    for i in ranked:
        if not counts and (i in alike or _never_a_branch(loc, i, exits)):
            continue
        fit = loc._fit(i, features, matched_all[i].rotation_rad, config.verify_inliers, exits, 0.0)
        if fit is None or fit.inliers < config.verify_inliers:
            continue
        repeats = True
        ports = loc._ports_of(i, exits, fit.rotation_rad)
        if ports is not None and not ports.agrees and config.port_check:
            continue
        if loc._hypotheses.arrival_conflict(i, ports, exits):
            continue
        i_exit = None if ports is None else ports.exit_ports
        i_arrival = None if behind is None or i_exit is None else i_exit[behind]
        branches.append(Branch(i, i_arrival, i_exit, loc._evidence(i, ports)))
        fits[i] = (matched_all[i], fit, ports)
    return repeats


def _repeats_far(
    loc: Localizer,
    branches: list[Branch],
    features: SweepFeatures,
    matched_all: list[SetMatch],
    exits: tuple[float, ...] | None,
) -> bool:
    """Whether the keypoints of the best ranked known junction beyond the odometry's
    reach fit the sweep (none of the branches): the look repeats, though that
    junction cannot be the visit's."""
    near, needed = loc._odometry.near, loc.config.verify_inliers
    other = _other(loc, branches, exits)
    ranked, _ = check_order(matched_all, lambda i: other(i) and not near(i), 1)
    for i in ranked:
        fit = loc._fit(i, features, matched_all[i].rotation_rad, needed, exits, 0.0)
        if fit is not None and fit.inliers >= needed:
            return True
    return False


def _other(
    loc: Localizer, branches: list[Branch], exits: tuple[float, ...] | None
) -> Callable[[int], bool]:
    """Whether a known junction may show that the look repeats: none of the
    branches, not the junction the robot just left, used by the map, and its pipes
    able to line up with the exits."""
    skip = {b.node for b in branches} | {loc._excluded()}
    topomap = loc.map

    def other(i: int) -> bool:
        return (
            i not in skip and not topomap.unused(i) and loc._allowed_rotations(i, exits, 0.0) != ()
        )

    return other


def _new_likelihood(loc: Localizer, branches: list[Branch]) -> float | None:
    """The log-likelihood of the new branch beside ``branches`` (see the module);
    ``None`` where it has none (no dead reckoning, or at a known junction's place)
    or would be pruned at once. More branches never raise it."""
    # Not at any of the known junctions it may be: the nearest by odometry counts.
    odometry = max(loc._odometry.log_likelihood(b.node) for b in branches)
    if odometry >= 0.0:
        return None
    log_likelihood = math.log(NEW_LIKELIHOOD) + math.log1p(-math.exp(odometry))
    best = max(b.log_likelihood for b in branches)
    if log_likelihood - best < math.log(loc.config.hypothesis_prune_ratio):
        return None
    return log_likelihood


def _never_a_branch(loc: Localizer, node: int, exits: tuple[float, ...] | None) -> bool:
    """Whether no two-view fit can make known junction ``node`` a branch: with the
    port check on, a fit whose ports do not agree is passed over, and at every
    assignment of the exits to the ports that one could agree with, the pipe end
    the robot came in by leads elsewhere (the arrival rule)."""
    config = loc.config
    return config.port_check and loc._hypotheses.arrival_conflict_at_every_turn(
        node, exits, config.port_tolerance_rad
    )
