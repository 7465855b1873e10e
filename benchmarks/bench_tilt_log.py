"""A recorded run's revisit rotations with and without the IMU's levelling and the
two-view tilt refinement.

    pipemap record --network paper --tilt-deg 3 -o tilted.mcap
    python benchmarks/bench_tilt_log.py tilted.mcap

Replays and scores the log four times: at pipemap's defaults (each sweep levelled by
its IMU reading, the tilt refinement then left out: both sweeps of a fit are levelled),
with ``TwoViewConfig.imu_level`` off (the refinement instead),
with ``TwoViewConfig.tilt`` off, and with both off; prints the map's status and the
largest and mean rotation error of the correct revisits (against the log's truth). For placement
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
    two_view = defaults.two_view_config
    variants = {
        "defaults (IMU levelling)": two_view,
        "no IMU levelling": replace(two_view, imu_level=False),
        "no tilt refinement": replace(two_view, tilt=False),
        "neither": replace(two_view, imu_level=False, tilt=False),
    }
    for name, variant in variants.items():
        config = replace(defaults, two_view_config=variant)
        report = api.score(log, config)
        errors = [
            abs(v.rotation_error_rad)
            for v in report.visits
            if v.outcome == "correct_known" and v.rotation_error_rad is not None
        ]
        worst = max(errors, default=float("nan"))
        mean = sum(errors) / len(errors) if errors else float("nan")
        print(
            f"{name:<42} map {report.map_status:<8} rotation error of {len(errors)} "
            f"revisits: max {worst:.4f} rad, mean {mean:.4f} rad"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
