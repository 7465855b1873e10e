"""Similarity of pairs of a replay's visit sweeps, split by the true junction: the
paper's Table 1 compares image sets this way (``pipemap score``'s ``pairs``)."""

from __future__ import annotations

import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pipemap.localizer import (
    FastConfig,
    ImageSet,
    PreparedSet,
    pairwise_matches,
    wrap_angle_rad,
)
from pipemap.recorder.schemas import TrueSweep
from pipemap.replay.logged import SeenSets
from pipemap.replay.replayer import ReplayResult

__all__ = ["MAX_DIFFERENT_PAIRS", "PairStatistics", "pair_statistics", "rounded", "summary"]

_DECIMALS = 6


def rounded(value: float | None) -> float | None:
    """``value`` to the reports' six decimals (``-0.0`` as ``0.0``); ``None`` stays."""
    if value is None:
        return None
    rounded = round(float(value), _DECIMALS)
    return 0.0 if rounded == 0 else rounded


def summary(values: list[float]) -> dict[str, Any]:
    """Mean, population standard deviation and count of ``values``, rounded."""
    if not values:
        return {"mean": None, "std": None, "n": 0}
    std = statistics.pstdev(values) if len(values) > 1 else 0.0
    return {"mean": rounded(statistics.fmean(values)), "std": rounded(std), "n": len(values)}


@dataclass(frozen=True)
class PairStatistics:
    """Every unordered pair of visit sweeps (probe sweeps aside), split by the truth:
    the paper's Table 1 compares image sets this way."""

    same: tuple[float, ...]
    different: tuple[float, ...]
    #: ``|estimate - true|`` of the rotation between the headings, same-junction pairs.
    rotation_errors_rad: tuple[float, ...]
    #: Pairs of different junctions in the log (``different`` may be a sample of them).
    different_total: int | None = None

    def document(self) -> dict[str, Any]:
        """Mean, std and count of each kind of pair; mean and max rotation error. A
        sample of the different pairs says of how many (``"of"``)."""
        errors = self.rotation_errors_rad
        different = summary(list(self.different))
        if self.different_total is not None and self.different_total > len(self.different):
            different["of"] = self.different_total
        return {
            "same": summary(list(self.same)),
            "different": different,
            "rotation_error_rad": {
                "mean": rounded(statistics.fmean(errors)) if errors else None,
                "max": rounded(max(errors)) if errors else None,
                "n": len(errors),
            },
        }


#: Pairs of visits of different junctions compared at most; more are sampled. A log of
#: 100 junctions (206 visits) has 21 115 pairs, 2 000 of a thousand about two million:
#: all of them took 45 s there and would take over an hour here. Pairs of one junction
#: are few (about as many as the visits) and always all compared.
MAX_DIFFERENT_PAIRS = 5000


def pair_statistics(
    result: ReplayResult,
    truths: dict[int, TrueSweep],
    fast: FastConfig | None = None,
    max_different: int = MAX_DIFFERENT_PAIRS,
) -> PairStatistics:
    """Similarity of pairs of a replay's visit sweeps, split by the true junction:
    every pair of one junction, and every pair of different ones up to
    ``max_different`` of them, beyond that an even sample of that many (seeded:
    the same log, the same pairs).

    The rotation of a pair is the localizer's estimate of the turn from the first
    visit's heading to the second's; its error is against the simulator's headings.
    The sets are compared as the localizer saw them (normalised under a lamp): as its
    matcher prepared them (:attr:`ReplayResult.visit_prepared`) when ``fast`` is the
    replay's, else made anew from :attr:`ReplayResult.visit_sets`.
    """
    asked = fast if fast is not None else FastConfig()
    prepared = result.visit_prepared if result.fast == asked else {}
    if result.visit_prepared and not prepared and not result.visit_sets:
        raise ValueError("the replay's sets were prepared with other matcher settings")
    ids = sorted(i for i in (prepared or result.visit_sets) if i in truths)
    nodes = [truths[i].node for i in ids]
    same_pairs: list[tuple[int, int]] = []
    different_pairs: list[tuple[int, int]] = []
    for i in range(len(ids)):
        for j in range(i + 1, len(ids)):
            (same_pairs if nodes[i] == nodes[j] else different_pairs).append((i, j))
    total_different = len(different_pairs)
    if total_different > max_different:
        rng = np.random.default_rng(0)
        keep = np.sort(rng.choice(total_different, size=max_different, replace=False))
        different_pairs = [different_pairs[k] for k in keep]
    sets: Sequence[ImageSet | PreparedSet] = (
        [prepared[i] for i in ids]
        if prepared
        else SeenSets(result.visit_sets, ids, result.illumination)
    )
    headings = [truths[i].yaw_rad - result.camera_angles[i] for i in ids]
    same: list[float] = []
    different: list[float] = []
    errors: list[float] = []
    matches = pairwise_matches(sets, fast, pairs=same_pairs + different_pairs)
    for (i, j), match in sorted(matches.items()):
        if nodes[i] == nodes[j]:
            same.append(match.similarity)
            true_turn = wrap_angle_rad(headings[j] - headings[i])
            errors.append(abs(wrap_angle_rad(match.rotation_rad - true_turn)))
        else:
            different.append(match.similarity)
    return PairStatistics(tuple(same), tuple(different), tuple(errors), total_different)
