"""How well the two-view check's keypoints tell a log's junctions apart, reduced and at
the closer look's keypoints.

    python benchmarks/two_view_pairs.py LOG [LOG ...] [--guesses N]

Takes every visit's own sweep of each log (lit as the localizer sees it) and the true
junction of each (``/truth/sweep``: for scoring only), then fits pairs with the
check's keypoints (:func:`pipemap.localizer.twoview.stored_features`: at 400 px the
images reduced to 200 px, 250 keypoints each) and with the closer look's
(:mod:`pipemap.localizer.closer`: the images themselves, 400 each):

- every pair of visits of one junction (within a log), at no guess (every image
  against every image, the rotation found from the matches);
- every pair of the first visits of two different junctions (within a log, and
  across the logs given), at no guess and at N guessed rotations around the circle
  (12 by default: a fit searches 0.3 rad either side of its guess), the most inliers
  of any.

A fit needs 6 inliers here (fewer: 0). Prints, for each kind of keypoints, the
fewest inliers of a same-junction pair (the five fewest, with the visits) and the
most of a different-junction pair (the five most).
"""

from __future__ import annotations

import argparse
import itertools
import math
import sys
from dataclasses import replace
from pathlib import Path

from pipemap.localizer import LocalizerConfig
from pipemap.localizer.closer import closer_config
from pipemap.localizer.twoview import SweepFeatures, fit_two_view, sweep_features
from pipemap.recorder import read_log, schemas
from pipemap.replay import FileSource, replay

TRUE_SWEEP = "/truth/sweep"


def _visits(path: Path) -> list[tuple[str, int, str, object]]:
    """(log, visit, true junction, lit image set) of each visit's own sweep."""
    truth = {}
    for m in read_log(path, lambda topic: topic == TRUE_SWEEP).messages:
        if m.topic == TRUE_SWEEP:
            t = schemas.TrueSweep.FromString(m.data)
            truth[t.sweep_id] = t.node
    result = replay(FileSource(path), None, keep_sets=True, recorded_threshold=True)
    lit = result.localizer._lit
    return [
        (path.name, v.visit_id, truth[v.sweep_id], lit(result.visit_sets[v.sweep_id]))
        for v in result.visits
    ]


def _inliers(a: SweepFeatures, b: SweepFeatures, config: object, guess: float | None) -> int:
    fit = fit_two_view(a, b, config, guess)  # type: ignore[arg-type]
    return 0 if fit is None else fit.inliers


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("logs", type=Path, nargs="+", metavar="LOG")
    parser.add_argument("--guesses", type=int, default=12, help="rotations guessed (12)")
    args = parser.parse_args()
    visits = [v for path in args.logs for v in _visits(path)]
    same = [
        (i, j)
        for i, j in itertools.combinations(range(len(visits)), 2)
        if visits[i][0] == visits[j][0] and visits[i][2] == visits[j][2]
    ]
    first: dict[tuple[str, str], int] = {}
    for k, (log, _, node, _) in enumerate(visits):
        first.setdefault((log, node), k)
    different = list(itertools.combinations(first.values(), 2))
    guesses: list[float | None] = [None]
    guesses += [-math.pi + (k + 1) * 2.0 * math.pi / args.guesses for k in range(args.guesses)]
    check = LocalizerConfig().two_view_config
    kinds = {
        "check (reduced)": check,
        "closer look (full detail)": closer_config(
            check, LocalizerConfig().closer_keypoints_per_image
        ),
    }
    name = ", ".join(p.name for p in args.logs)
    print(
        f"# {name}: {len(visits)} visits, {len(same)} pairs of one junction, "
        f"{len(different)} of different junctions ({args.guesses} guesses and none)"
    )
    for label, config in kinds.items():
        loose = replace(config, min_inliers=6, min_inlier_share=0.0, accept_share=0.0)
        features = [sweep_features(v[3], config) for v in visits]  # type: ignore[arg-type]

        def tag(k: int) -> str:
            return f"{visits[k][0]}:{visits[k][1]}"

        ones = sorted(
            (_inliers(features[j], features[i], loose, None), tag(j), tag(i)) for i, j in same
        )
        others = sorted(
            (
                (max(_inliers(features[i], features[j], loose, g) for g in guesses), tag(i), tag(j))
                for i, j in different
            ),
            reverse=True,
        )
        print(f"{label}: one junction, fewest inliers {ones[:5]}")
        print(f"{label}: different junctions, most inliers {others[:5]}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
