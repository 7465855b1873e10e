"""The localizer: junction recognition and topological mapping, pure.

Depends on numpy, scipy, opencv and networkx only: no files, no simulator, no logs,
no clock (a caller may give :class:`Localizer` one to time its phases by). Its inputs
and outputs are the types exported here.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
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
        prepare,
    )
    from pipemap.localizer.illumination import IlluminationConfig, normalised
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
    from pipemap.localizer.mapjson import (
        FLOAT_DECIMALS,
        decision_record,
        dumps_document,
        map_document,
    )
    from pipemap.localizer.pairwise import for_pairs, pairwise_matches, prepare_for_pairs
    from pipemap.localizer.phases import PHASES
    from pipemap.localizer.ports import (
        PORT_TOLERANCE_RAD,
        PortMatch,
        clockwise_ports,
        match_ports,
        nearest_exit,
    )
    from pipemap.localizer.presets import (
        PAPER_THRESHOLD,
        ROBUST_HIGHPASS_FRACTION,
        ROBUST_THRESHOLD,
        ROBUST_ZOOMS,
    )
    from pipemap.localizer.routes import (
        RouteStep,
        describe_step,
        nearest_route,
        plan_route,
        route_length_m,
    )
    from pipemap.localizer.similarity import (
        PAPER_SCALE,
        PairPeak,
        SetMatch,
        best_offset,
        ncc_same,
        pair_peak,
        paper_scaled,
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
        overlapping_images,
        sweep_features,
    )

#: Where each public name lives. Loaded on first use (PEP 562): the command line
#: imports :mod:`pipemap.localizer.presets` for its help without paying for numpy,
#: scipy and OpenCV.
_EXPORTS = {
    "ExploreConfig": "pipemap.localizer.explore",
    "ExploreEnd": "pipemap.localizer.explore",
    "ExploreStep": "pipemap.localizer.explore",
    "MapExplorer": "pipemap.localizer.explore",
    "Planner": "pipemap.localizer.explore",
    "RouteFollower": "pipemap.localizer.explore",
    "PORT_TOLERANCE_RAD": "pipemap.localizer.ports",
    "PortMatch": "pipemap.localizer.ports",
    "clockwise_ports": "pipemap.localizer.ports",
    "match_ports": "pipemap.localizer.ports",
    "nearest_exit": "pipemap.localizer.ports",
    "RouteStep": "pipemap.localizer.routes",
    "describe_step": "pipemap.localizer.routes",
    "nearest_route": "pipemap.localizer.routes",
    "plan_route": "pipemap.localizer.routes",
    "route_length_m": "pipemap.localizer.routes",
    "MapVisit": "pipemap.localizer.topomap",
    "PAPER_THRESHOLD": "pipemap.localizer.presets",
    "ROBUST_HIGHPASS_FRACTION": "pipemap.localizer.presets",
    "ROBUST_THRESHOLD": "pipemap.localizer.presets",
    "ROBUST_ZOOMS": "pipemap.localizer.presets",
    "DEFAULT_FOV_RAD": "pipemap.localizer.imageset",
    "DEFAULT_KEEP_TOP_FRACTION": "pipemap.localizer.imageset",
    "DEFAULT_THRESHOLD": "pipemap.localizer.config",
    "Decision": "pipemap.localizer.decision",
    "FLOAT_DECIMALS": "pipemap.localizer.mapjson",
    "FastConfig": "pipemap.localizer.fastmatch",
    "FastMatcher": "pipemap.localizer.fastmatch",
    "IlluminationConfig": "pipemap.localizer.illumination",
    "ImageSet": "pipemap.localizer.imageset",
    "Localizer": "pipemap.localizer.localizer",
    "LocalizerConfig": "pipemap.localizer.config",
    "MapEdge": "pipemap.localizer.topomap",
    "PAPER": "pipemap.localizer.config",
    "PAPER_SCALE": "pipemap.localizer.similarity",
    "PHASES": "pipemap.localizer.phases",
    "PairPeak": "pipemap.localizer.similarity",
    "PreparedSet": "pipemap.localizer.fastmatch",
    "ProbeKind": "pipemap.localizer.decision",
    "ProbeOutcome": "pipemap.localizer.decision",
    "ProbeRequest": "pipemap.localizer.decision",
    "ProbeSource": "pipemap.localizer.decision",
    "SetMatch": "pipemap.localizer.similarity",
    "SweepFeatures": "pipemap.localizer.twoview",
    "TopoMap": "pipemap.localizer.topomap",
    "TwoViewConfig": "pipemap.localizer.twoview",
    "TwoViewFit": "pipemap.localizer.twoview",
    "best_candidate": "pipemap.localizer.decision",
    "best_offset": "pipemap.localizer.similarity",
    "decision_record": "pipemap.localizer.mapjson",
    "dumps_document": "pipemap.localizer.mapjson",
    "fit_two_view": "pipemap.localizer.twoview",
    "for_pairs": "pipemap.localizer.pairwise",
    "overlapping_images": "pipemap.localizer.twoview",
    "map_document": "pipemap.localizer.mapjson",
    "ncc_same": "pipemap.localizer.similarity",
    "normalised": "pipemap.localizer.illumination",
    "pair_peak": "pipemap.localizer.similarity",
    "paper_scaled": "pipemap.localizer.similarity",
    "pairwise_matches": "pipemap.localizer.pairwise",
    "prepare_for_pairs": "pipemap.localizer.pairwise",
    "pinhole_rotation_rad": "pipemap.localizer.similarity",
    "prepare": "pipemap.localizer.fastmatch",
    "probe_plan": "pipemap.localizer.decision",
    "reference_match": "pipemap.localizer.similarity",
    "relative_rotation_rad": "pipemap.localizer.similarity",
    "sweep_features": "pipemap.localizer.twoview",
    "wrap_angle_rad": "pipemap.localizer.similarity",
}


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'pipemap.localizer' has no attribute {name!r}")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


__all__ = [
    "DEFAULT_FOV_RAD",
    "DEFAULT_KEEP_TOP_FRACTION",
    "DEFAULT_THRESHOLD",
    "PAPER_THRESHOLD",
    "ROBUST_HIGHPASS_FRACTION",
    "ROBUST_THRESHOLD",
    "ROBUST_ZOOMS",
    "FLOAT_DECIMALS",
    "PAPER",
    "PAPER_SCALE",
    "PHASES",
    "Decision",
    "ExploreConfig",
    "ExploreEnd",
    "ExploreStep",
    "FastConfig",
    "FastMatcher",
    "IlluminationConfig",
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
    "for_pairs",
    "overlapping_images",
    "map_document",
    "match_ports",
    "nearest_exit",
    "nearest_route",
    "ncc_same",
    "normalised",
    "pair_peak",
    "paper_scaled",
    "pinhole_rotation_rad",
    "plan_route",
    "pairwise_matches",
    "prepare",
    "prepare_for_pairs",
    "probe_plan",
    "reference_match",
    "relative_rotation_rad",
    "route_length_m",
    "sweep_features",
    "wrap_angle_rad",
]
