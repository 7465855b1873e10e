"""Why the two-view check did or did not fit a visit of a log with its candidates.

    python benchmarks/why_two_view.py LOG VISIT [--save PATH]

Replays LOG at the defaults (the recorded threshold, as ``pipemap score LOG``) and,
for visit VISIT (its number in the log), prints each two-view fit the localizer
made with a known junction: the guess it started from and the inliers it needed,
then the check's stages (:mod:`pipemap.localizer.stages`) redone on the same
keypoints: the keypoints of each sweep, the matches at the guess (each image with
the images it can overlap), the best count on the coarse grid after each stage
against what that stage's gate asks, and the refined fit's inliers with every
stage matched; then the same pair on the closer look's keypoints
(:mod:`pipemap.localizer.closer`). Last, the decision as ``pipemap -v score``
prints it.

``--save PATH`` writes the visit's sweep and those of the junctions it was fitted
with, as the log holds them (8-bit frames), with their exits and departures, to a
compressed ``.npz`` (what ``tests/localizer/test_closer_look.py`` reads).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from pipemap.localizer import Localizer
from pipemap.localizer.closer import closer_config
from pipemap.localizer.keymatch import _matches, _merged, overlapping_images
from pipemap.localizer.stages import _coarse
from pipemap.localizer.twoview import SweepFeatures, TwoViewConfig, fit_two_view, sweep_features
from pipemap.recorder import read_log
from pipemap.replay import FileSource, replay
from pipemap.replay.logged import node_events_of, sweeps_of
from pipemap.replay.source import ordered


def _stages(
    query: SweepFeatures, known: SweepFeatures, guess: float, config: TwoViewConfig
) -> list[str]:
    """The check's matching and fit redone stage by stage, one line each."""
    overlap = overlapping_images(query, known, guess, config.overlap_margin_rad)
    ratio = config.ratio if overlap is None else config.overlap_ratio
    tolerance = config.inlier_px * max(query.pixel_rad, known.pixel_rad)
    stages = max(1, config.gate_every)
    part = np.arange(len(known)) % stages
    gate = config.gate_share * config.min_inliers / stages
    lines = [
        f"    keypoints: visit {len(query)}, junction {len(known)}; inlier within "
        f"{tolerance:.4f} rad ({config.inlier_px} px)"
    ]
    found: list[tuple[np.ndarray, np.ndarray]] = []
    for stage in range(stages):
        found.append(_matches(query, known, ratio, overlap, part == stage))
        merged = _merged(known, found)
        counts, _, _ = _coarse(query, known, merged, guess, config, tolerance)
        asked = int(gate * (stage + 1)) if stage < stages - 1 else config.min_inliers
        lines.append(
            f"    stage {stage + 1}/{stages}: {len(merged[0])} matches, best coarse count "
            f"{int(counts.max(initial=0))} (gate asks {asked})"
        )
    loose = replace(config, min_inliers=6, min_inlier_share=0.0, gate_every=1, accept_share=0.0)
    fit = fit_two_view(query, known, loose, guess)
    if fit is None:
        lines.append("    refined: fewer than 6 inliers")
    else:
        lines.append(
            f"    refined: {fit.inliers} inliers of {fit.matches} matches, rotation "
            f"{fit.rotation_rad:+.4f} rad, direction {fit.direction_rad:.3f} rad "
            f"(asked {config.min_inliers})"
        )
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("visit", type=int, help="the visit's number in the log")
    parser.add_argument("--save", type=Path, help="write the sweeps fitted to this .npz")
    args = parser.parse_args()

    fits: list[dict[str, Any]] = []
    state = {"visit": 0}
    real_localize, real_fit = Localizer.localize, Localizer._fit

    def localize(self: Localizer, *a: Any, **k: Any) -> Any:
        state["visit"] += 1
        return real_localize(self, *a, **k)

    def fit(self: Localizer, node: int, features: SweepFeatures, guess: float, needed: int,
            exits: Any, turn: float, closer: Any = None) -> Any:  # fmt: skip
        result = real_fit(self, node, features, guess, needed, exits, turn, closer)
        if state["visit"] == args.visit:
            fits.append(
                {"node": node, "guess": guess, "needed": needed, "result": result, "closer": closer}
            )
        return result

    Localizer.localize = localize  # type: ignore[method-assign,assignment,unused-ignore]
    Localizer._fit = fit  # type: ignore[method-assign,assignment,unused-ignore]
    result = replay(FileSource(args.log), None, keep_sets=True, recorded_threshold=True)
    Localizer.localize, Localizer._fit = real_localize, real_fit  # type: ignore[method-assign,unused-ignore]

    visits = {v.visit_id: v for v in result.visits}
    if args.visit not in visits:
        print(f"no visit {args.visit} in {args.log}", file=sys.stderr)
        return 2
    config = result.localizer.config
    lit = result.localizer._lit
    # The sweep each junction keeps is its first visit's (decided new).
    first = {v.decision.node: v for v in result.visits if not v.decision.known}
    sets = result.visit_sets
    query_set = lit(sets[visits[args.visit].sweep_id])
    print(f"{args.log} visit {args.visit}: {len(fits)} fit(s) with a known junction")
    for f in fits:
        node, guess, needed = f["node"], f["guess"], f["needed"]
        known_set = lit(sets[first[node].sweep_id])
        got = f["result"]
        verdict = "none" if got is None else f"{got.inliers} inliers"
        print(
            f"  junction {node} (first seen at visit {first[node].visit_id}): guess "
            f"{guess:+.4f} rad, needs {needed}"
            f"{' (the junction the map expects: a closer look if short)' if f['closer'] else ''}"
            f": {verdict}"
        )
        for label, tv in (
            ("reduced (the check)", config.two_view_config),
            (
                "closer look (full detail)",
                closer_config(config.two_view_config, config.closer_keypoints_per_image),
            ),
        ):
            print(f"   {label}:")
            asked = replace(tv, min_inliers=max(tv.min_inliers, needed))
            q, k = sweep_features(query_set, tv), sweep_features(known_set, tv)
            print("\n".join(_stages(q, k, guess, asked)))
    print(f"  decision: {visits[args.visit].decision.describe()}")
    if args.save is not None:
        _save(args, visits, first, fits)
    return 0


def _save(args: Any, visits: Any, first: Any, fits: Any) -> None:
    """The raw sweeps (visit first, then each fitted junction's) and their scans."""
    messages = ordered(read_log(args.log).messages)
    raw = {s.sweep_id: s for s in sweeps_of(messages).sweeps if s.probe is None}
    scans = node_events_of(messages)
    wanted = [args.visit] + [first[f["node"]].visit_id for f in fits]
    out: dict[str, np.ndarray] = {}
    for visit_id in dict.fromkeys(wanted):
        sweep = raw[visits[visit_id].sweep_id]
        scan = scans.get(visit_id)
        out[f"frames_{visit_id}"] = sweep.frames
        out[f"camera_{visit_id}"] = np.array([sweep.fov_rad, sweep.camera_angle_rad])
        exits = () if scan is None or scan.exits_rad is None else scan.exits_rad
        out[f"exits_{visit_id}"] = np.array(exits, dtype=np.float64)
        departure = math.nan if scan is None or scan.departure_rad is None else scan.departure_rad
        out[f"departure_{visit_id}"] = np.array([departure])
    out["visits"] = np.array(list(dict.fromkeys(wanted)))
    np.savez_compressed(args.save, **out)
    print(f"  saved {', '.join(map(str, out['visits']))} to {args.save}")


if __name__ == "__main__":
    sys.exit(main())
