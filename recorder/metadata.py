"""The types of the log's metadata values.

MCAP metadata maps strings to strings, so the ``pipemap.run`` and ``pipemap.result``
records hold every number as text. Readers that hand metadata on (``pipemap info
--json``, the Python API) turn them back into numbers with :func:`typed_metadata`,
by name, so that a value that does not parse stays visible as the text it is.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["METADATA_TYPES", "lamp_strength", "odometry_drift", "typed_metadata"]


def _bool(text: str) -> bool:
    if text not in ("true", "false"):
        raise ValueError(text)
    return text == "true"


#: How each known key of ``pipemap.run`` and ``pipemap.result`` is parsed.
METADATA_TYPES: dict[str, Callable[[str], Any]] = {
    "seed": int,
    "resolution_px": int,
    "images_per_sweep": int,
    "fov_rad": float,
    "align_sweeps": _bool,
    "threshold": float,
    "odometry_drift": float,
    "simulator": json.loads,
    "sweeps": int,
    "visits": int,
    "distance_m": float,
    "duration_ns": int,
}


def typed_metadata(record: Mapping[str, str]) -> dict[str, Any]:
    """``record`` with every known key's value parsed to its type; other keys, and
    values that do not parse, stay the strings they are."""
    typed: dict[str, Any] = {}
    for key, text in record.items():
        parse = METADATA_TYPES.get(key)
        try:
            typed[key] = text if parse is None else parse(text)
        except ValueError:
            typed[key] = text
    return typed


def lamp_strength(run: Mapping[str, str]) -> float:
    """The robot's lamp, relative to full (1.0), as the run's simulator settings
    record it; 0.0 (even light) where they do not say, or are not JSON."""
    try:
        settings = json.loads(run.get("simulator", "{}"))
        value = settings["camera"]["lamp_strength"]
    except (ValueError, KeyError, TypeError):
        return 0.0
    return float(value) if isinstance(value, (int, float)) else 0.0


def odometry_drift(run: Mapping[str, str]) -> float:
    """How many times as poor as the default robot's the run's odometry was
    (``record --odometry-drift``); 1.0 where the settings do not say, or say no
    number of at least 1."""
    try:
        value = float(run.get("odometry_drift", "1"))
    except ValueError:
        return 1.0
    return value if math.isfinite(value) and value >= 1.0 else 1.0
