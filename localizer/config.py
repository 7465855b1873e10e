"""The localizer's settings: :class:`LocalizerConfig`, and :data:`PAPER`, the paper's
decision rule. What each rule does: :mod:`localizer.localizer`."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

from pipemap.errors import LocalizerError
from pipemap.localizer.fastmatch import FastConfig
from pipemap.localizer.illumination import IlluminationConfig
from pipemap.localizer.ports import PORT_TOLERANCE_RAD
from pipemap.localizer.presets import PAPER_THRESHOLD
from pipemap.localizer.twoview import TwoViewConfig

__all__ = [
    "COST_SWITCHES",
    "DEFAULT_THRESHOLD",
    "PAPER",
    "PIPEMAP_CHECKS",
    "PIPEMAP_REFINEMENTS",
    "LocalizerConfig",
]

#: The localizer's default threshold: the paper's (see :mod:`.presets`).
DEFAULT_THRESHOLD = PAPER_THRESHOLD

#: The checks pipemap adds to the paper's decision, each a switch of
#: :class:`LocalizerConfig`; the paper's rule (:meth:`LocalizerConfig.paper_rule`,
#: :data:`PAPER`) has none of them.
PIPEMAP_CHECKS = ("distinct_consecutive", "two_view", "verify", "port_check", "odometry_check")
#: Switches that refine one of those checks (and do nothing without it); the paper's
#: rule turns them off with it.
PIPEMAP_REFINEMENTS = ("odometry_heading_bias",)
#: Switches that trade memory for time and change no decision; every rule keeps them
#: as set.
COST_SWITCHES = ("closer_keeps_images",)


@dataclass(frozen=True)
class LocalizerConfig:
    """Settings of the localizer; the defaults are the paper's except the checks of
    pipemap's own (:data:`PIPEMAP_CHECKS`): ``distinct_consecutive``, ``two_view``,
    ``verify``, ``port_check`` and ``odometry_check``. :data:`PAPER` turns all of them
    off."""

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
    #: The junction the map says the robot's pipe leads to (:meth:`Localizer.expected_node`)
    #: is recognised with this many inliers (its ports must still fit): the map is
    #: evidence too. A revisit back out of a dead end, seen from the pipe's mouth, fit
    #: its junction with 33 inliers at 200 px (``random:17`` seed 7, visit 18) while
    #: the best other junction fit with 17; distractors reached 20 at most
    #: (``benchmarks/bench_localizer.py --check-distractors``).
    expected_inliers: int = 24
    #: When the expected junction's fit falls short on images the check reduced, fit it
    #: again on keypoints of the images at their own size, up to 400 px (this many an
    #: image; :mod:`localizer.closer`). 0: no closer look. Part of the two-view check
    #: (``verify``), not a check of its own.
    closer_keypoints_per_image: int = 400
    #: Keep each new junction's 8-bit images for a closer look and find their
    #: keypoints only when one is taken (469 KiB a junction at 400 px); off: find
    #: them at once (83 KiB, and ORB's time in every new junction's decision).
    closer_keeps_images: bool = True
    #: A sweep with fewer keypoints is decided by the threshold (a 32 px sweep has
    #: about 25, a 96 px one about 2000).
    verify_min_keypoints: int = 200
    #: With the visit's exits given: a candidate is recognised only if the exits,
    #: turned by the measured rotation, line up with its ports within
    #: ``port_tolerance_rad`` (see :mod:`localizer.ports`). Not in the paper.
    port_check: bool = True
    port_tolerance_rad: float = PORT_TOLERANCE_RAD
    #: With the visit's dead reckoning given: a known junction is a candidate only if
    #: the robot is within ``odometry_radius_m`` plus ``odometry_drift_per_m`` per
    #: metre driven (at most ``odometry_limit_m``) of where it was at that junction's
    #: first visit. What appearance cannot fake: junctions that look alike
    #: (``record --alike``) are still apart. The numbers are the explorer's odometry
    #: check's (:class:`localizer.explore.ExploreConfig`): a revisit's dead reckoning
    #: was at most 0.39 m off after some 60 m, and the simulator's junctions are at
    #: least 0.8 m apart. Not in the paper.
    odometry_check: bool = True
    odometry_radius_m: float = 0.3
    odometry_drift_per_m: float = 0.005
    odometry_limit_m: float = 0.6
    #: A junction first seen long ago may also be this much of the distance driven
    #: since then from the robot's dead reckoning, when that is more than the
    #: tolerance above (:meth:`localizer.odometry.DeadReckoning.tolerance_for`). On
    #: ``random:200`` seed 4711 at 96 px a loop closed 0.61 m off after 252 m (0.24 %);
    #: 0.4 % passes the limit only after 150 m.
    odometry_loop_drift_per_m: float = 0.004
    #: The robot's heading error grows with the distance it drives (a gyro's bias left
    #: over after its estimate, over the robot's speed): this many radians a metre. A
    #: heading error swings the path driven after it, so a junction may also lie this
    #: times the path's moment since its first visit (in m², see
    #: :class:`localizer.odometry.PathMoment`) plus ``odometry_radius_m`` away, when that
    #: is more than the tolerances above. On ``random:200`` seed 4711 with pipes of
    #: 1-20 m the dead reckoning's error was 3.8e-4 of the moment (9.5 m after 779 m of
    #: driving), on the short-pipe layout 1.5e-4 to 2.6e-4.
    odometry_heading_drift_per_m: float = 0.0006
    #: Estimate that drift from the loops the robot closes (each recognised revisit)
    #: and take it out of the dead reckoning before the check
    #: (:class:`localizer.odometry.HeadingBias`); the allowance above then narrows to
    #: what the fit leaves uncertain, down to ``odometry_heading_residual_per_m``.
    odometry_heading_bias: bool = True
    #: How far the heading's drift may stray from its fit (rad/m): on ``random:200``
    #: seed 4711 with pipes of 1-20 m it was 3.7e-4 to 3.8e-4 at every revisit.
    odometry_heading_residual_per_m: float = 0.0001
    #: A known visit's other candidates that passed the same checks and matched within
    #: this of the recognised junction's similarity are named as alike
    #: (``Decision.alike``): junctions nothing told apart.
    alike_margin: float = 0.02
    #: Where junctions named alike also fit the sweep's keypoints and ports, keep a
    #: map for each (:mod:`localizer.hypotheses`): at most this many live at once
    #: (1: one map, the best ranked junction is taken), and one weighing less than
    #: ``hypothesis_prune_ratio`` of the best is dropped. Not in the paper.
    hypotheses: int = 8
    hypothesis_prune_ratio: float = 0.01
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

    def paper_rule(self) -> LocalizerConfig:
        """These settings with the paper's decision rule (Algorithm 1): the similarity
        threshold alone decides known or new, every known junction competes (the
        previous visit's included), the rotation is the NCC peak shift's, and neither
        the exits nor the dead reckoning are compared. The threshold, the similarity,
        active vision (the paper's Algorithm 3) and the illumination stay as set."""
        off: dict[str, Any] = dict.fromkeys((*PIPEMAP_CHECKS, *PIPEMAP_REFINEMENTS), False)
        return replace(self, **off)

    def __post_init__(self) -> None:
        if not -1.0 <= self.threshold <= 1.0:
            raise LocalizerError(f"threshold must be in [-1, 1], got {self.threshold}")
        if not (self.probe_distance_m >= 0.0 and math.isfinite(self.probe_distance_m)):
            raise LocalizerError(f"probe distance must be >= 0 m, got {self.probe_distance_m}")
        if self.verify and not self.two_view:
            raise LocalizerError("verify decides by the two-view fit: it needs two_view")
        if self.verify_inliers < 1 or self.verify_candidates < 1 or self.expected_inliers < 1:
            raise LocalizerError(
                "verify_inliers, expected_inliers and verify_candidates must be >= 1"
            )
        if self.closer_keypoints_per_image < 0:
            raise LocalizerError("closer_keypoints_per_image must be >= 0")
        odometry = (
            self.odometry_radius_m,
            self.odometry_drift_per_m,
            self.odometry_limit_m,
            self.odometry_loop_drift_per_m,
            self.odometry_heading_drift_per_m,
            self.odometry_heading_residual_per_m,
            self.alike_margin,
        )
        if self.hypotheses < 1 or not 0.0 < self.hypothesis_prune_ratio < 1.0:
            raise LocalizerError(
                f"hypotheses must be >= 1 and their prune ratio in (0, 1), got "
                f"{self.hypotheses} and {self.hypothesis_prune_ratio}"
            )
        if not all(math.isfinite(v) and v >= 0.0 for v in odometry):
            raise LocalizerError(f"odometry tolerances must be finite and >= 0, got {odometry}")
        if not 0.0 < self.port_tolerance_rad < math.pi / 2.0:
            raise LocalizerError(
                f"port tolerance must be in (0, pi/2) rad, got {self.port_tolerance_rad}"
            )


#: The paper's decision rule at the paper's threshold (see
#: :meth:`LocalizerConfig.paper_rule`): ``pipemap score --rule paper``, the batch rule
#: ``paper``.
PAPER = LocalizerConfig().paper_rule()
