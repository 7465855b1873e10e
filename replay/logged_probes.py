"""Probe requests answered from a log: the probe sweeps a visit's robot made, and the
moves it refused.

A replay (:mod:`replay.replayer`) and a live view (:mod:`replay.live`) answer the
localizer's active-vision requests from the probe sweeps logged with the visit. A
request the log cannot answer is missing, unless the robot refused that move (its
rangers found a wall within it; the log's warning says so) or makes no probe moves
at all (:func:`makes_probes`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from pipemap.localizer import Decision, ImageSet, Localizer, ProbeRequest
from pipemap.replay.logged import LoggedSweep

__all__ = ["LoggedProbes", "answer_probes", "makes_probes"]

#: A probe in the log answers a request for the same kind and move: its steps to
#: this much, its turn to ``_PROBE_TURN_MATCH_RAD``. The turn is the NCC's estimate of
#: the rotation, so any change to the arithmetic (another localizer version, another
#: FFT) moves it in the last digits; the camera cannot tell such turns apart: 1e-3
#: rad is under a third of a pixel at 400 px (80 degrees over 400 columns).
_PROBE_MATCH = 1e-9
_PROBE_TURN_MATCH_RAD = 1e-3


def makes_probes(metadata: dict[str, str] | None) -> bool:
    """Whether the run's robot makes the probe moves active vision asks for: in the
    ``active`` placement condition, and in the ``autonomous`` one unless its metadata
    turns them off (``recorder.session``); a log that does not name its condition is
    taken to, so a missing probe is reported as missing."""
    condition = None if metadata is None else metadata.get("condition")
    if condition == "autonomous":
        assert metadata is not None
        return metadata.get("probe_moves", "true") != "false"
    return condition is None or condition == "active"


class LoggedProbes:
    """Answers probe requests from the probe sweeps the log holds for one visit (their
    image sets made here, before the decision: they are the camera's, not its work)."""

    def __init__(self, probes: list[LoggedSweep], refused: Sequence[str] = ()) -> None:
        self.probes = [(sweep.probe, sweep.images) for sweep in probes]
        self.refused_kinds = list(refused)
        self.not_in_log = 0
        #: Requests the robot refused to move for (the log's warning says so).
        self.refused = 0

    def probe(self, request: ProbeRequest) -> ImageSet | None:
        for probe, images in self.probes:
            assert probe is not None
            kind, yaw, forward, left = probe
            if (
                kind == request.kind.value
                and abs(math.remainder(yaw - request.yaw_rad, 2.0 * math.pi))
                <= _PROBE_TURN_MATCH_RAD
                and math.isclose(forward, request.forward_m, rel_tol=0.0, abs_tol=_PROBE_MATCH)
                and math.isclose(left, request.left_m, rel_tol=0.0, abs_tol=_PROBE_MATCH)
            ):
                return images
        if request.kind.value in self.refused_kinds:
            self.refused_kinds.remove(request.kind.value)
            self.refused += 1
        else:
            self.not_in_log += 1
        return None


def answer_probes(
    localizer: Localizer,
    images: ImageSet,
    probes: list[LoggedSweep],
    exits_rad: tuple[float, ...] | None = None,
    odometer_m: float | None = None,
    position_m: tuple[float, float] | None = None,
    refused: Sequence[str] = (),
) -> tuple[Decision, int, int]:
    """``localizer``'s decision for a visit's ``images`` (and its exit scan, if
    logged), its probe requests answered from the visit's logged ``probes``; how
    many requests the log could not answer, and how many of those the robot refused
    to move for (``refused``: the kinds of its refused moves, as its log says)."""
    answers = LoggedProbes(probes, refused)
    decision = localizer.localize(images, answers, exits_rad, odometer_m, position_m)
    return decision, answers.not_in_log, answers.refused
