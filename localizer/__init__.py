"""The localizer: junction recognition and topological mapping, pure.

Depends on numpy, scipy, opencv and networkx only: no files, no simulator, no logs,
no clock. Its inputs and outputs are the types exported here.
"""

from __future__ import annotations

from pipemap.localizer.explore import (
    ExploreConfig,
    ExploreEnd,
    ExploreStep,
    MapExplorer,
    Planner,
    RouteFollower,
)
from pipemap.localizer.fastmatch import (
    FastConfig,
    FastMatcher,
    PreparedSet,
    pairwise_matches,
    prepare,
)
from pipemap.localizer.imageset import DEFAULT_FOV_RAD, DEFAULT_KEEP_TOP_FRACTION, ImageSet
from pipemap.localizer.localizer import (
    DEFAULT_THRESHOLD,
    PAPER,
    Decision,
    Localizer,
    LocalizerConfig,
    ProbeKind,
    ProbeOutcome,
    ProbeRequest,
    ProbeSource,
    best_candidate,
    probe_plan,
)
from pipemap.localizer.mapjson import FLOAT_DECIMALS, decision_record, dumps_document, map_document
from pipemap.localizer.ports import (
    PORT_TOLERANCE_RAD,
    PortMatch,
    clockwise_ports,
    match_ports,
    nearest_exit,
)
from pipemap.localizer.routes import (
    RouteStep,
    describe_step,
    nearest_route,
    plan_route,
    route_length_m,
)
from pipemap.localizer.similarity import (
    PairPeak,
    SetMatch,
    best_offset,
    ncc_same,
    pair_peak,
    pinhole_rotation_rad,
    reference_match,
    relative_rotation_rad,
    wrap_angle_rad,
)
from pipemap.localizer.topomap import MapEdge, MapVisit, TopoMap
from pipemap.localizer.twoview import (
    SweepFeatures,
    TwoViewConfig,
    TwoViewFit,
    fit_two_view,
    sweep_features,
)

__all__ = [
    "DEFAULT_FOV_RAD",
    "DEFAULT_KEEP_TOP_FRACTION",
    "DEFAULT_THRESHOLD",
    "FLOAT_DECIMALS",
    "PAPER",
    "Decision",
    "ExploreConfig",
    "ExploreEnd",
    "ExploreStep",
    "FastConfig",
    "FastMatcher",
    "ImageSet",
    "Localizer",
    "LocalizerConfig",
    "MapEdge",
    "MapExplorer",
    "MapVisit",
    "PORT_TOLERANCE_RAD",
    "Planner",
    "PairPeak",
    "PortMatch",
    "PreparedSet",
    "ProbeKind",
    "ProbeOutcome",
    "ProbeRequest",
    "ProbeSource",
    "RouteFollower",
    "RouteStep",
    "SetMatch",
    "SweepFeatures",
    "TopoMap",
    "TwoViewConfig",
    "TwoViewFit",
    "best_offset",
    "best_candidate",
    "clockwise_ports",
    "describe_step",
    "decision_record",
    "dumps_document",
    "fit_two_view",
    "map_document",
    "match_ports",
    "nearest_exit",
    "nearest_route",
    "ncc_same",
    "pair_peak",
    "pinhole_rotation_rad",
    "plan_route",
    "pairwise_matches",
    "prepare",
    "probe_plan",
    "reference_match",
    "relative_rotation_rad",
    "route_length_m",
    "sweep_features",
    "wrap_angle_rad",
]
