"""The localizer: junction recognition and topological mapping, pure.

Depends on numpy, scipy, opencv and networkx only: no files, no simulator, no logs,
no clock. Its inputs and outputs are the types exported here.
"""

from __future__ import annotations

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
from pipemap.localizer.topomap import MapEdge, TopoMap
from pipemap.localizer.twoview import (
    SweepFeatures,
    TwoViewConfig,
    TwoViewFit,
    fit_two_view,
    overlapping_images,
    sweep_features,
)

__all__ = [
    "DEFAULT_FOV_RAD",
    "DEFAULT_KEEP_TOP_FRACTION",
    "DEFAULT_THRESHOLD",
    "FLOAT_DECIMALS",
    "PAPER",
    "PAPER_SCALE",
    "Decision",
    "FastConfig",
    "FastMatcher",
    "ImageSet",
    "Localizer",
    "LocalizerConfig",
    "MapEdge",
    "PairPeak",
    "PreparedSet",
    "ProbeKind",
    "ProbeOutcome",
    "ProbeRequest",
    "ProbeSource",
    "SetMatch",
    "SweepFeatures",
    "TopoMap",
    "TwoViewConfig",
    "TwoViewFit",
    "best_offset",
    "best_candidate",
    "decision_record",
    "dumps_document",
    "fit_two_view",
    "overlapping_images",
    "map_document",
    "ncc_same",
    "pair_peak",
    "paper_scaled",
    "pinhole_rotation_rad",
    "pairwise_matches",
    "prepare",
    "probe_plan",
    "reference_match",
    "relative_rotation_rad",
    "sweep_features",
    "wrap_angle_rad",
]
