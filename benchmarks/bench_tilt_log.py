"""A recorded run's revisit rotations with and without the two-view tilt refinement.

    pipemap record --network paper --tilt-deg 3 -o tilted.mcap
    python benchmarks/bench_tilt_log.py tilted.mcap

Replays and scores the log twice, at pipemap's defaults and with
``TwoViewConfig.tilt`` off, and prints the map's status and the largest and mean
rotation error of the correct revisits (against the log's truth). For placement
runs rendered directly, without a log, see ``bench_tilt.py``.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from pipemap import api
from pipemap.localizer import LocalizerConfig


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    args = parser.parse_args()
    log = api.open_log(args.log)
    defaults = LocalizerConfig()
    untilted = replace(defaults.two_view_config, tilt=False)
    for name, config in (
        ("with the tilt refinement", defaults),
        ("without it", replace(defaults, two_view_config=untilted)),
    ):
        report = api.score(log, config)
        errors = [
            abs(v.rotation_error_rad)
            for v in report.visits
            if v.outcome == "correct_known" and v.rotation_error_rad is not None
        ]
        worst = max(errors, default=float("nan"))
        mean = sum(errors) / len(errors) if errors else float("nan")
        print(
            f"{name:<25} map {report.map_status:<8} rotation error of {len(errors)} "
            f"revisits: max {worst:.4f} rad, mean {mean:.4f} rad"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
