"""The two-view check's matching in stages, and its coarse search for a start.

:func:`_staged_matches` matches the known sweep's keypoints a share at a time
(:attr:`TwoViewConfig.gate_every`) and gives a pair of sweeps up as soon as the
matches so far cannot fit one motion well enough (the gate, counted on the coarse
grid of :func:`localizer.epipolar._grid_counts`; the first share is matched in two
halves, with an early gate after the first, :func:`_first_stage`). :func:`_coarse_start` is the
coarse search that starts the fit's refinement: on every rotation around the
matches' azimuth peak and the guess, or, when the last gate's grid already found
a clear peak, only around it. A pair whose first stages already fit clearly
stops matching there (:attr:`TwoViewConfig.accept_share`), and a fit compared with
such a one matches as many stages (:attr:`TwoViewConfig.stage_limit`). Why:
:mod:`localizer.twoview`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pipemap.localizer.epipolar import _azimuth_peak, _grid_counts
from pipemap.localizer.keymatch import MatchCache, _matches, _merged

if TYPE_CHECKING:
    from pipemap.localizer.twoview import SweepFeatures, TwoViewConfig


@dataclass(frozen=True)
class _Staged:
    """The matches of every stage (:func:`_merged`'s order) and the coarse grid of
    the last gate counted: its counts, rotations and what that gate asked (``None``
    without a gate)."""

    found: tuple[np.ndarray, np.ndarray]
    gate_counts: np.ndarray | None = None
    gate_rotations: np.ndarray | None = None
    gate_needed: int = 0
    #: Stages matched: all of them (``gate_every``), or fewer when the fit stopped
    #: early or was limited.
    stages: int = 1


def _rotations(centres: list[float], config: TwoViewConfig) -> np.ndarray:
    offsets = np.linspace(-config.search_rad, config.search_rad, config.rotation_steps)
    return np.concatenate([centre + offsets for centre in centres])


def _centres(
    query: SweepFeatures,
    known: SweepFeatures,
    found: tuple[np.ndarray, np.ndarray],
    guess: float | None,
    config: TwoViewConfig,
) -> list[float]:
    """The azimuth peak of the matches ``found`` (first), and the guess if any; the
    guess alone when ``config.around_peak`` is off (and there is one)."""
    if guess is not None and not config.around_peak:
        return [guess]
    a, b = query.bearings[found[0]], known.bearings[found[1]]
    return [_azimuth_peak(a, b)] + ([] if guess is None else [guess])


def _coarse(
    query: SweepFeatures,
    known: SweepFeatures,
    found: tuple[np.ndarray, np.ndarray],
    guess_rad: float | None,
    config: TwoViewConfig,
    tolerance: float,
) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """The coarse search of :func:`fit_two_view` on the matches ``found``: the counts
    of every rotation (around the azimuth peak and the guess) and direction, the
    rotations, and the centres they lie around (the peak first)."""
    a, b = query.bearings[found[0]], known.bearings[found[1]]
    if len(a) == 0:
        return np.zeros((0, config.direction_steps), np.int64), np.zeros(0), []
    centres = _centres(query, known, found, guess_rad, config)
    rotations = _rotations(centres, config)
    counts = _grid_counts(a, b, rotations, config.direction_steps, tolerance)
    return counts, rotations, centres


def _asked_stages(config: TwoViewConfig) -> int:
    """The stages a fit is asked to match: all (``gate_every``), or ``stage_limit``."""
    stages = max(1, config.gate_every)
    return stages if config.stage_limit <= 0 else min(stages, config.stage_limit)


def _staged_matches(
    query: SweepFeatures,
    known: SweepFeatures,
    ratio: float,
    overlap: list[np.ndarray] | None,
    guess_rad: float | None,
    config: TwoViewConfig,
    tolerance: float,
    cache: MatchCache | None = None,
) -> _Staged | None:
    """The matches of :func:`_matches`, found in ``config.gate_every`` stages of the
    known sweep's keypoints; ``None`` as soon as the matches so far fall short of a
    stage's gate (see :attr:`TwoViewConfig.gate_every`).

    Only the first ``config.stage_limit`` stages are matched, if it is set: the
    gates then ask what a fit of all stages asked ``min_inliers`` times
    ``gate_every / stage_limit`` would, so ``min_inliers`` is what those stages'
    matches must fit. Without a limit, the matching stops after a stage whose count
    on the coarse grid reaches ``config.accept_share`` times ``min_inliers`` (see
    :attr:`TwoViewConfig.accept_share`); the count is the one a gate makes anyway.
    """
    stages = max(1, config.gate_every)
    depth = _asked_stages(config)
    bar = config.min_inliers * stages / depth  # the gates' bar, as for a fit of every stage
    gate = config.gate_share * bar / stages
    part = np.arange(len(known)) % stages
    # A first gate below 3 stops nothing: any two matches fit some motion.
    if stages == 1 or int(gate) < 3:
        only = None if depth == stages else part < depth
        return _Staged(_matches(query, known, ratio, overlap, only, cache), stages=depth)
    first = _first_stage(
        known,
        lambda only: _matches(query, known, ratio, overlap, only, cache),
        lambda found: int(
            _coarse(query, known, found, guess_rad, config, tolerance)[0].max(initial=0)
        ),
        config,
        bar,
    )
    if first is None:
        return None
    early_stop = config.accept_share > 0 and depth == stages
    accept = config.accept_share * config.min_inliers if early_stop else math.inf
    found: list[tuple[np.ndarray, np.ndarray]] = [first]
    count = 0
    grid: tuple[np.ndarray, np.ndarray, int] | None = None
    for stage in range(depth):
        if stage > 0:
            found.append(_matches(query, known, ratio, overlap, part == stage, cache))
        needed = int(gate * (stage + 1))
        # More matches never lower a count: a gate the last count passes is passed.
        if stage < depth - 1 and count < needed:
            if sum(len(f[0]) for f in found) < needed:
                return None  # too few matches for any cell to count what it asks
            counts, rotations, _ = _coarse(
                query, known, _merged(known, found), guess_rad, config, tolerance
            )
            count = int(counts.max(initial=0))
            if count < needed:
                return None
            grid = (counts, rotations, needed)
            if count >= accept:
                return _Staged(_merged(known, found), *grid, stages=stage + 1)
    if grid is None:
        return _Staged(_merged(known, found), stages=depth)
    return _Staged(_merged(known, found), *grid, stages=depth)


def _first_stage(
    known: SweepFeatures,
    match: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    best_count: Callable[[tuple[np.ndarray, np.ndarray]], int],
    config: TwoViewConfig,
    bar: float,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The first stage's matches (:func:`_merged`'s order), found in two halves with
    the early gate of :attr:`TwoViewConfig.early_gate_share` after the first;
    ``None`` when the first half falls short of it. The gate only gives up: the
    matches, and every later gate, are those of one first stage. ``match`` matches
    the known keypoints a mask marks, ``best_count`` is the coarse grid's best
    count of some matches, ``bar`` what a fit of every stage must fit (the gates'
    ``min_inliers``)."""
    stages = max(1, config.gate_every)
    early = int(config.early_gate_share * bar / (2 * stages))
    part = np.arange(len(known)) % (2 * stages)
    if early < 3:  # stops nothing (see _staged_matches): one call
        return _merged(known, [match(part % stages == 0)])
    half = match(part == 0)
    # A pair counts once in a cell at most: fewer matches than the gate asks fail it.
    if len(half[0]) < early or best_count(_merged(known, [half])) < early:
        return None
    return _merged(known, [half, match(part == stages)])


def _coarse_start(
    query: SweepFeatures,
    known: SweepFeatures,
    staged: _Staged,
    guess_rad: float | None,
    config: TwoViewConfig,
    tolerance: float,
) -> tuple[float, float, list[float]]:
    """Where the fit's refinement starts: the first best rotation of the coarse grid
    on all the matches, its first best direction of motion; and the centres of the
    grid's rotations (the azimuth peak first).

    When the last gate's grid found at least twice what that gate asked, only the
    rotations within ``config.local_steps`` steps of its best are counted (on the
    same rotations as the whole grid, in the same order)."""
    found = staged.found
    a, b = query.bearings[found[0]], known.bearings[found[1]]
    centres = _centres(query, known, found, guess_rad, config)
    rotations = _rotations(centres, config)
    gate = staged.gate_counts
    if gate is not None and staged.gate_rotations is not None and config.local_steps > 0:
        per_rotation = gate.max(axis=1)
        best = int(np.argmax(per_rotation))
        if per_rotation[best] >= config.min_inliers:
            step = 2.0 * config.search_rad / max(1, config.rotation_steps - 1)
            reach = (config.local_steps + 0.5) * step
            # Rotations a turn apart are one (the two centres may lie either side of pi).
            gap = np.mod(rotations - staged.gate_rotations[best] + math.pi, 2.0 * math.pi)
            near = np.abs(gap - math.pi) <= reach
            if near.any():
                rotations = rotations[near]
    counts = _grid_counts(a, b, rotations, config.direction_steps, tolerance)
    directions = np.linspace(0.0, math.pi, config.direction_steps, endpoint=False)
    per_rotation = counts.max(axis=1)
    r = int(np.argmax(per_rotation))  # the first best rotation, its first best direction
    return float(rotations[r]), float(directions[int(np.argmax(counts[r]))]), centres
