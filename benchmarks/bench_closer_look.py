"""What the two-view check's closer look costs: time and memory, on one core.

    python benchmarks/bench_closer_look.py [--repeat N]

On the two 400 px lamp-lit sweeps of ``tests/localizer/data/random17_seed7_visits_6_18.npz``
(one junction, swept 10.4 cm apart; see ``localizer/closer.py``), with BLAS, FFT and
OpenCV threads pinned to one:

1. ORB keypoints of one sweep as the check computes them (reduced to 200 px, 250 an
   image) and as the closer look computes them (the images at their own size, 400 an
   image), and the bytes a known junction keeps of each: what every new junction now
   costs in addition;
2. the decision of the revisit (visit 18) by a localizer that knows the junction and
   expects it (the walk of ``tests/localizer/test_closer_look.py``), with the closer
   look (it is taken, and fits) and without (the visit is new);
3. the decision of visit 6's sweep by a localizer that knows nothing yet (a new
   junction), with ``LocalizerConfig.closer_keeps_images`` on (the default: it keeps
   the images ORB would see and finds no closer-look keypoints) and off (it finds
   them at once), and what each keeps for the closer look.

CPU time, the quickest of N tries (5 by default), in milliseconds.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import copy  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

cv2.setNumThreads(1)

from pipemap.localizer import ImageSet, Localizer, LocalizerConfig, normalised  # noqa: E402
from pipemap.localizer.closer import closer_config  # noqa: E402
from pipemap.localizer.twoview import stored_features  # noqa: E402

DATA = (
    Path(__file__).resolve().parents[1]
    / "tests"
    / "localizer"
    / "data"
    / "random17_seed7_visits_6_18.npz"
)


def _sweep(data: Any, visit: int) -> ImageSet:
    fov, angle = data[f"camera_{visit}"]
    return ImageSet(data[f"frames_{visit}"], fov_rad=float(fov), camera_angle_rad=float(angle))


def _quickest(repeat: int, work: Callable[[Any], object], setup: Callable[[], Any]) -> float:
    """The quickest of ``repeat`` runs of ``work`` on what ``setup`` makes (untimed)."""
    best = math.inf
    for _ in range(repeat):
        made = setup()
        start = time.process_time()
        work(made)
        best = min(best, time.process_time() - start)
    return best * 1e3


def _revisit(data: Any, closer_look: bool) -> Localizer:
    """A localizer that has seen visit 6's junction and a dead end beyond it, back
    from the dead end: it expects visit 6's junction."""
    keypoints = LocalizerConfig().closer_keypoints_per_image if closer_look else 0
    loc = Localizer(LocalizerConfig(lamp=True, closer_keypoints_per_image=keypoints))
    loc.localize(_sweep(data, 6), exits_rad=tuple(data["exits_6"]))
    loc.depart(float(data["exits_6"][0]))
    noise = np.random.default_rng(7).integers(0, 256, data["frames_6"].shape, dtype=np.uint8)
    loc.localize(ImageSet(noise, fov_rad=float(data["camera_6"][0])), exits_rad=(math.pi,))
    loc.depart(math.pi)
    return loc


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="tries of each (5)")
    args = parser.parse_args()
    data = np.load(DATA)
    config = LocalizerConfig()
    lit = normalised(_sweep(data, 6), config.illumination)
    check = config.two_view_config
    closer = closer_config(check, config.closer_keypoints_per_image)
    print(f"# {DATA.name}, 400 px, one core, quickest of {args.repeat}, CPU ms")
    for label, tv in (("check (reduced)", check), ("closer look (full detail)", closer)):
        ms = _quickest(args.repeat, lambda tv: stored_features(lit, tv), lambda tv=tv: tv)
        kept = stored_features(lit, tv)
        print(
            f"keypoints {label}: {ms:.1f} ms a sweep, {len(kept)} keypoints, "
            f"{kept.nbytes / 1024:.1f} KiB kept a junction"
        )
    query, exits = _sweep(data, 18), tuple(data["exits_18"])
    for closer_look in (True, False):
        loc = _revisit(data, closer_look)
        decision = copy.deepcopy(loc).localize(query, exits_rad=exits)
        ms = _quickest(
            args.repeat,
            lambda c: c.localize(query, exits_rad=exits),
            lambda loc=loc: copy.deepcopy(loc),
        )
        fit = decision.two_view
        print(
            f"revisit, closer look {'on' if closer_look else 'off'}: {ms:.1f} ms, "
            f"{'known' if decision.known else 'new'}"
            f"{'' if fit is None else f', {fit.inliers} inliers'}"
        )
    first, first_exits = _sweep(data, 6), tuple(data["exits_6"])
    for keeps_images in (True, False):
        fresh = Localizer(LocalizerConfig(lamp=True, closer_keeps_images=keeps_images))
        ms = _quickest(
            args.repeat,
            lambda c: c.localize(first, exits_rad=first_exits),
            lambda fresh=fresh: copy.deepcopy(fresh),
        )
        fresh.localize(first, exits_rad=first_exits)
        print(
            f"new junction, closer_keeps_images {'on' if keeps_images else 'off'}: "
            f"{ms:.1f} ms, {fresh._closer.nbytes / 1024:.1f} KiB kept for the closer look"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
