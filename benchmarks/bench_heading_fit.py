"""What the odometry check's heading fit costs as a run grows to town scale.

    python benchmarks/bench_heading_fit.py [--visits 400,1000,2100] [--leg-m 6] [--seed 0]

The fit (:class:`pipemap.localizer.odometry.HeadingBias`) is refitted at every
recognised revisit, over every visit and every closed loop so far, so its cost grows
with the run. A recorded 1000-junction run does not exist yet, so this draws a
synthetic one: a path of ``--visits`` visits whose legs are 1 to ``--leg-m`` metres
long with random turns (6 by default, 3.5 m on average: the 200-junction long-pipe
run drove 1299 m in 377 visits, 3.4 m a leg), and after
each visit past the tenth, with probability one half, a revisit of an earlier visit
(about as many revisits as new junctions, as the recorded runs have: 177 of 377 on
the 200-junction long-pipe run). Each revisit closes a loop and times the refit (CPU
time of this process, one BLAS thread as every pipemap command runs).

A 1000-junction run makes about 2100 visits (issue 41's estimate; the 200-junction
run made 377). Prints one JSON object per size: visits, closed loops, knots at the
end, and the refit's CPU milliseconds (median, 90th percentile, most, the mean of the
last ten) and CPU seconds in all.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from pipemap.localizer.odometry import HeadingBias  # noqa: E402

#: The odometry check's capped tolerance (``LocalizerConfig.odometry_limit_m``), the
#: fit's sigma.
SIGMA_M = 0.6
#: The path's moment handed to each refit (m²): it only adds to the fit's information.
MOMENT_M2 = 100.0


def run(visits: int, leg_m: float, seed: int) -> dict[str, float]:
    """Draw one synthetic run and time the refit at each of its revisits."""
    rng = np.random.default_rng(seed)
    bias = HeadingBias(SIGMA_M)
    x = y = odometer = heading = 0.0
    cpu_ms: list[float] = []
    for visit in range(visits):
        leg = float(rng.uniform(1.0, leg_m))
        heading += float(rng.normal(0.0, 1.0))
        odometer += leg
        x += leg * math.cos(heading)
        y += leg * math.sin(heading)
        point = bias.add(x, y, odometer)
        if visit > 10 and rng.random() < 0.5:
            first = int(rng.integers(0, point - 5))
            start = time.process_time()
            bias.close(first, point, MOMENT_M2)
            cpu_ms.append(1e3 * (time.process_time() - start))
    t = np.asarray(cpu_ms)
    return {
        "visits": visits,
        "closed_loops": len(bias.closures),
        "knots": len(bias.knots),
        "refit_cpu_ms_median": round(float(np.median(t)), 2),
        "refit_cpu_ms_p90": round(float(np.percentile(t, 90)), 2),
        "refit_cpu_ms_most": round(float(t.max()), 2),
        "refit_cpu_ms_last10": round(float(t[-10:].mean()), 2),
        "refit_cpu_s_total": round(float(t.sum()) / 1e3, 2),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--visits", default="400,1000,2100", help="sizes, comma-separated")
    parser.add_argument("--leg-m", type=float, default=6.0, help="longest leg (m)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    for size in (int(v) for v in args.visits.split(",")):
        print(json.dumps(run(size, args.leg_m, args.seed)), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
