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

Ports: the caller may pass the junction's exits (the pipes the robot's range scan
found, relative to its heading). A new junction keeps them as its ports; a revisit's
exits, turned by the measured rotation, must line up with the known junction's ports
(:mod:`localizer.ports`), or the candidate is passed over (the visit is new when none
is left): a false merge corrupts the map's topology, a false new node only costs a
second look. :meth:`Localizer.depart` records the port the robot leaves by.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from pipemap.localizer.branching import Fit, alike_branches, new_branch
from pipemap.localizer.closer import CloserLook
from pipemap.localizer.config import DEFAULT_THRESHOLD, PAPER, LocalizerConfig
from pipemap.localizer.decision import (
    Decision,
    ProbeKind,
    ProbeOutcome,
    ProbeRequest,
    ProbeSource,
    alike_candidates,
    best_candidate,
    check_order,
    probe_plan,
    threshold_candidates,
)
from pipemap.localizer.fastmatch import FastMatcher, PreparedSet
from pipemap.localizer.fitcache import VisitFits, fit_once
from pipemap.localizer.hypotheses import Branch, Hypotheses, port_log_likelihood
from pipemap.localizer.illumination import normalised
from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.odometry import DeadReckoning
from pipemap.localizer.phases import PhaseClock
from pipemap.localizer.ports import PortMatch, clockwise_ports, match_ports, port_rotations
from pipemap.localizer.ports import nearest_exit as _nearest_exit
from pipemap.localizer.similarity import SetMatch
from pipemap.localizer.topomap import TopoMap
from pipemap.localizer.twoview import StoredFeatures, SweepFeatures, TwoViewFit, stored_features

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

#: A departure heading (and the arrival, straight behind) names the exit nearest to
#: it within this: half the smallest angle between two pipes of a junction (60
#: degrees), so never two exits.
_DEPARTURE_TOLERANCE_RAD = math.pi / 6.0


class Localizer:
    """Known/new decisions over a growing database of junctions, and the map."""

    def __init__(
        self, config: LocalizerConfig | None = None, clock: Callable[[], float] | None = None
    ) -> None:
        self.config = config if config is not None else LocalizerConfig()
        #: A clock in seconds (``time.perf_counter``) to time each decision's phases
        #: by (:mod:`localizer.phases`); ``None``: none are timed.
        self._clock = clock
        #: Seconds of the last decision in each phase (empty without a clock).
        self.last_phases: dict[str, float] = {}
        self._matcher = FastMatcher(self.config.fast)
        #: Keypoints by node (with ``config.two_view``), computed once per sweep, kept compact.
        self._features: list[StoredFeatures] = []
        self._fits = VisitFits()
        self._closer = CloserLook(self.config)  # more keypoints (localizer.closer)
        self._hypotheses = Hypotheses(
            TopoMap(), self.config.hypotheses, self.config.hypothesis_prune_ratio
        )
        self._last: Decision | None = None
        self._odometry = DeadReckoning(self.config)
        #: The last visit's own sweep as the matcher prepared it (lit), for whoever
        #: compares visits later (a score's pairs); ``None`` before the first.
        self.last_prepared: PreparedSet | None = None

    @property
    def map(self) -> TopoMap:
        """The topological map: the heaviest hypothesis's (:mod:`localizer.hypotheses`)."""
        return self._hypotheses.leader.map

    @map.setter
    def map(self, topomap: TopoMap) -> None:
        """Go on from ``topomap`` as the one map (any other hypotheses are dropped)."""
        config = self.config
        self._hypotheses = Hypotheses(topomap, config.hypotheses, config.hypothesis_prune_ratio)

    @property
    def open_visits(self) -> dict[int, tuple[int, ...]]:
        """The visits (by index in the map's visit order) that the live hypotheses
        give different junctions, each with those junctions, the map's first: what
        nothing has told apart yet."""
        return dict(self._hypotheses.open)

    @property
    def hypotheses_alive(self) -> int:
        """The number of live hypotheses (maps)."""
        return len(self._hypotheses.live)

    def hypothesis_exits(self) -> tuple[tuple[TopoMap, tuple[int, ...] | None], ...]:
        """Each live map, heaviest first, with the port of each exit of the last visit
        in it (what the explorer tells maps apart by)."""
        return tuple((h.map, h.exit_ports) for h in self._hypotheses.live)

    @property
    def dead_reckoning(self) -> DeadReckoning:
        """The robot's dead reckoning at the visits decided so far, with the heading's
        drift fitted to the loops they closed (what the explorer checks positions by)."""
        return self._odometry

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
        matches = self._matcher.match(prepared, exclude, self._expected_nodes())
        best, sim, margin = best_candidate(matches, exclude)
        return matches, best, sim, margin

    def _ports_of(
        self, node: int, exits: tuple[float, ...] | None, rotation_rad: float | None
    ) -> PortMatch | None:
        """Whether ``exits`` fit ``node``'s ports after ``rotation_rad``; ``None`` when
        there is nothing to compare (no exits, no ports, no rotation)."""
        ports = self.map.ports(node)
        if exits is None or ports is None or rotation_rad is None:
            return None
        return match_ports(ports, exits, rotation_rad, self.config.port_tolerance_rad)

    def localize(
        self,
        query: ImageSet,
        probes: ProbeSource | None = None,
        exits_rad: Sequence[float] | None = None,
        odometer_m: float | None = None,
        position_m: tuple[float, float] | None = None,
    ) -> Decision:
        """Decide known or new for one junction visit, and add the visit to the map.

        The image set stored for a new junction is the visit's own sweep (not a
        probe's), so every junction is remembered as seen from its centre.
        ``exits_rad`` are the junction's pipes as the robot found them, relative to
        its heading during the sweep (0 ahead, positive to the left); with them the
        map gets ports. ``odometer_m`` (distance driven so far) gives edges a length.
        ``position_m`` (dead reckoning, in the start's frame) rules out, with
        ``odometry_check``, the known junctions too far from where they were.
        """
        self._odometry.at(position_m, odometer_m)
        timer = PhaseClock(self._clock)
        exits = None if exits_rad is None else tuple(float(e) for e in exits_rad)
        query = self._lit(query)
        prepared = self._matcher.prepare(query)
        self.last_prepared = prepared
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
        ports: PortMatch | None = None
        rejected: list[tuple[int, str]] = []
        alike: tuple[int, ...] = ()
        timer.lap("ncc")
        if self.config.two_view:
            stored = stored_features(matched, self.config.two_view_config)
            features = stored.features()
            timer.lap("keypoints")
        if features is not None and self.config.verify and self._checkable(features):
            verified = self._verified(features, matched_all, turn, exits, rejected, matched)
            known = verified is not None
            if verified is not None:
                best, raw_fit, ports, alike = verified
                match = matched_all[best].turned(turn)
                sim = match.similarity
                fit = raw_fit.turned(turn)
        else:
            known = False
            for i in threshold_candidates(
                matched_all,
                best,
                sim,
                self.config,
                self._excluded(),
                lambda i: self._odometry.near(i) and not self.map.unused(i),
            ):
                i_match = match if i == best else matched_all[i].turned(turn)
                assert i_match is not None
                i_fit = None
                if features is not None:
                    raw = self._fit(i, features, matched_all[i].rotation_rad, 0, exits, turn)
                    i_fit = None if raw is None else raw.turned(turn)
                rotation = i_fit.rotation_rad if i_fit is not None else i_match.rotation_rad
                i_ports = self._ports_of(i, exits, rotation)
                if i_ports is not None and not i_ports.agrees and self.config.port_check:
                    rejected.append((i, i_ports.reason))
                    continue
                known, best, match, sim, fit, ports = (
                    True,
                    i,
                    i_match,
                    i_match.similarity,
                    i_fit,
                    i_ports,
                )
                break
        timer.lap("check")
        new_ports = None
        if known:
            assert best is not None
            node = best
            exit_ports = None if ports is None else ports.exit_ports
        else:
            node = self._matcher.add(prepared)
            self._odometry.remember(node)
            if stored is not None:
                if matched is not query:  # a probe's: remember the visit's own sweep
                    timer.lap("map")
                    stored = stored_features(query, self.config.two_view_config)
                    timer.lap("keypoints")
                self._features.append(stored)
                self._closer.keep(node, query)
            exit_ports = None
            if exits is not None:
                new_ports, exit_ports = clockwise_ports(exits)
        behind = None
        if exits is not None and self.map.previous is not None:
            behind = _nearest_exit(exits, math.pi, _DEPARTURE_TOLERANCE_RAD)
        arrival = None if behind is None or exit_ports is None else exit_ports[behind]
        branches = [Branch(node, arrival, exit_ports, self._evidence(node, ports))]
        fits: dict[int, Fit] = {node: (match, fit, ports)}
        if known and features is not None and self.config.hypotheses > 1:
            branches += alike_branches(
                self, alike, features, matched_all, turn, exits, behind, fits
            )
            own = stored if matched is query else None
            grown = new_branch(
                self, branches, alike, features, matched_all, exits, behind, prepared, own, fits
            )
            if grown is not None:
                branches, new_ports = [*branches, grown[0]], grown[1]
        settled = self._hypotheses.visit(branches, new_ports, odometer_m)
        index = self.map.visit_count - 1
        last = self.map.last_visit
        assert last is not None
        if last.node != node:  # another branch weighs more at once (or the visit is new)
            node, arrival, known = last.node, last.arrival_port, last.node in fits
            match, fit, ports = fits.get(node, (match, None, None))
            assert match is not None
            best, sim = (node, match.similarity) if known else (best, sim)
            exit_ports = self._hypotheses.leader.exit_ports
        decision = Decision(
            node=node,
            known=known,
            candidate=best,
            similarity=sim,
            margin=margin,
            match=match,
            probes=tuple(outcomes),
            two_view=fit,
            exits_rad=exits,
            exit_ports=exit_ports,
            arrival_port=arrival,
            port_residual_rad=None if ports is None else ports.residual_rad,
            rejected=tuple(rejected),
            alike=alike,
            hypotheses=len(self._hypotheses.live),
            deferred=tuple(n for n in self._hypotheses.open.get(index, ()) if n != node),
            settled=settled,
        )
        if known:
            self._odometry.closed(node)
        self._last = decision
        timer.lap("map")
        self.last_phases = timer.seconds
        return decision

    def _expected_nodes(self) -> list[int]:
        """The junctions the map puts near the robot: the one it expects next and the
        neighbours of the last one (screened whatever the index ranks them)."""
        previous = self.map.previous
        if previous is None:
            return []
        expected = self.expected_node()
        near = []
        for port in range(len(self.map.ports(previous) or ())):
            edge = self.map.edge_at(previous, port)
            if edge is not None:
                near.append(edge.other(previous, port)[0])
        return ([] if expected is None else [expected]) + near

    def expected_node(self) -> int | None:
        """The junction the map says the robot is coming to: the far end of the edge
        at the port it left its last junction by (``None`` when the map does not know:
        an untraversed pipe, no ports, a traversal's first visit)."""
        previous = self.map.previous
        if previous is None:
            return None
        last = self.map.last_visit
        port = None if last is None else last.departure_port
        edge = None if port is None else self.map.edge_at(previous, port)
        return None if edge is None or port is None else edge.other(previous, port)[0]

    def depart(self, exit_rad: float | None) -> int | None:
        """Record that the robot leaves the junction of its last visit by the exit at
        ``exit_rad`` (relative to its heading during the sweep): the exit nearest to
        it, within half the smallest junction angle (a robot turning straight back
        leaves at pi, its scan may have put that pipe a little off). Returns that
        port, or ``None`` when it is not known (no exits, or none near)."""
        last = self._last
        index = None
        if exit_rad is not None and last is not None and last.exits_rad is not None:
            index = _nearest_exit(last.exits_rad, exit_rad, _DEPARTURE_TOLERANCE_RAD)
        return self._hypotheses.depart(index)

    def block(self) -> int | None:
        """The robot gave up the pipe it last left by and is back at the junction of
        its last visit: that port is blocked (:meth:`TopoMap.block`). Returns it."""
        return self._hypotheses.block()

    def new_traversal(self) -> None:
        """The next visit does not follow the last (the robot starts a new run on this
        map): no edge joins them, and the last junction is a candidate again."""
        self._hypotheses.new_traversal()
        self._last = None

    def _evidence(self, node: int, ports: PortMatch | None) -> float:
        """The visit's log-likelihood of being known junction ``node`` (odometry, ports)."""
        tolerance = self.config.port_tolerance_rad
        return self._odometry.log_likelihood(node) + port_log_likelihood(ports, tolerance)

    def _lit(self, image_set: ImageSet) -> ImageSet:
        """The set as the matcher sees it: normalised if lamp-lit."""
        return normalised(image_set, self.config.illumination) if self.config.lamp else image_set

    def _checkable(self, features: SweepFeatures) -> bool:
        """Enough keypoints for the two-view check to decide; with fewer (images of a
        few dozen pixels), the threshold decides, as in the paper."""
        return len(features) >= self.config.verify_min_keypoints

    #: The two-view fit of the sweep with a known junction, once a visit for the same
    #: question (:func:`localizer.fitcache.fit_once`).
    _fit = fit_once

    def _allowed_rotations(
        self, node: int, exits: tuple[float, ...] | None, turn: float
    ) -> tuple[float, ...] | None:
        """The rotations (from the matched sweep's heading, ``turn`` after the visit's)
        at which the exits line up with ``node``'s ports; ``None`` when there is
        nothing to compare (no port check, no exits, no ports)."""
        ports = self.map.ports(node)
        if not self.config.port_check or exits is None or ports is None:
            return None
        allowed = port_rotations(ports, exits, self.config.port_tolerance_rad)
        return tuple(math.remainder(r - turn, 2.0 * math.pi) for r in allowed)

    def _agrees(self, node: int, exits: tuple[float, ...] | None, rotation_rad: float) -> bool:
        """Whether a fit at ``rotation_rad`` (from the visit's heading) passes the port
        check (it does when there is nothing to check)."""
        ports = self._ports_of(node, exits, rotation_rad)
        return ports is None or ports.agrees or not self.config.port_check

    def _verified(
        self,
        features: SweepFeatures,
        matches: list[SetMatch],
        turn: float,
        exits: tuple[float, ...] | None,
        rejected: list[tuple[int, str]],
        matched: ImageSet | None = None,
    ) -> tuple[int, TwoViewFit, PortMatch | None, tuple[int, ...]] | None:
        """The first of the junction the map expects (:meth:`expected_node`) and the
        best junctions (refined ones first, each by similarity) that the sweep's
        keypoints fit and whose ports the exits fit, with that fit (unturned) and the
        ports; ``None`` if none does. Candidates whose keypoints fit but whose ports
        do not go to ``rejected``."""
        exclude = self._excluded()

        # A junction whose pipes cannot line up with the exits at any turn is not the
        # visit's (the port check would pass it over), nor one the robot is too far
        # from by odometry: neither takes a candidate's place.
        def allowed(i: int) -> bool:
            return (
                0 <= i < len(matches)
                and i != exclude
                and not self.map.unused(i)
                and self._allowed_rotations(i, exits, turn) != ()
                and self._odometry.near(i)
            )

        # Refined junctions first, then screened ones: the two scores differ in scale.
        ranked, screened = check_order(matches, allowed, self.config.verify_candidates)
        # The junction the map says this pipe leads to goes first: the similarity may
        # rank it low (a revisit from another pipe, seen from a little off the centre)
        # while its keypoints fit with hundreds of inliers.
        expected = self.expected_node()
        if expected is not None and allowed(expected):
            ranked = [expected, *(i for i in ranked if i != expected)]
        for i in ranked:
            # The map's junction needs fewer inliers (``expected_inliers``), and gets a
            # closer look. A fit with fewer would not count: let it stop as soon as it
            # knows (so only the junction that fits pays for the tilted refinement).
            needed = self.config.expected_inliers if i == expected else self.config.verify_inliers
            closer = matched if i == expected else None
            fit = self._fit(i, features, matches[i].rotation_rad, needed, exits, turn, closer)
            if fit is not None and fit.inliers >= needed:
                ports = self._ports_of(i, exits, fit.turned(turn).rotation_rad)
                if ports is not None and not ports.agrees and self.config.port_check:
                    rejected.append((i, ports.reason))
                    continue
                conflict = self._hypotheses.arrival_conflict(i, ports, exits)
                if conflict is not None:
                    rejected.append((i, conflict))
                    continue
                return (
                    i,
                    fit,
                    ports,
                    alike_candidates(  # a junction rejected was told apart
                        i,
                        expected,
                        lambda k: allowed(k) and k not in dict(rejected),
                        matches,
                        screened,
                        self.config.alike_margin,
                    ),
                )
        return None
