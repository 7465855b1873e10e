"""Benchmark of the localizer on the paper's image sets: speed, agreement, memory.

Prints, on one core (BLAS and FFT threads pinned to 1 before numpy loads):

1. per-pair time of the reference and of the fast path at full resolution;
2. agreement of the fast path with the reference over every pair of the shared
   sets (image shift, known/unknown decision, similarity, rotation);
3. per-decision latency against databases of 1, 10, 100 and 1000 known junctions,
   synthetic ones made from augmented copies of the shared images;
4. memory kept per known junction.

Usage: ``python benchmarks/bench_localizer.py [--sets DIR] [--reference-pairs K]
[--write-reference FILE]``. The reference over all 55 pairs takes a few minutes;
``--reference-pairs K`` times it on K pairs and compares agreement on those only.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import itertools  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

cv2.setNumThreads(1)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from localizer import (  # noqa: E402
    DEFAULT_THRESHOLD,
    FastConfig,
    FastMatcher,
    ImageSet,
    pairwise_matches,
    reference_match,
    wrap_angle_rad,
)
from pipemap.folders import load_image_set, read_info  # noqa: E402

DEFAULT_SETS = ROOT.parent / "shared" / "paper_imagesets"


def augmented_set(base: list[ImageSet], rng: np.random.Generator) -> ImageSet:
    """A plausible distractor: images of one or two base sets, rolled, mirrored, relit."""
    first = base[int(rng.integers(len(base)))].images
    second = base[int(rng.integers(len(base)))].images
    n = first.shape[0]
    take = rng.random(n) < 0.5
    images = np.where(take[:, None, None], first, second)
    images = np.roll(images, int(rng.integers(n)), axis=0)
    if rng.random() < 0.5:
        images = images[::-1, :, ::-1]
    gain = rng.uniform(0.7, 1.3)
    offset = rng.uniform(-20, 20)
    shift = int(rng.integers(-40, 41))
    images = np.roll(images, shift, axis=2) * gain + offset
    images = images + rng.normal(0.0, 3.0, images.shape)
    return ImageSet(np.clip(images, 0, 255).astype(np.float32))


def time_call(fn, repeat: int) -> float:  # type: ignore[no-untyped-def]
    """Median wall time of ``fn()`` in seconds."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=Path, default=DEFAULT_SETS)
    parser.add_argument("--reference-pairs", type=int, default=0, help="0: all pairs")
    parser.add_argument("--write-reference", type=Path, default=None)
    parser.add_argument("--sizes", default="1,10,100,1000")
    args = parser.parse_args()

    names = sorted(p.name for p in args.sets.iterdir() if p.is_dir())
    sets = {n: load_image_set(args.sets / n) for n in names}
    info = {n: read_info(args.sets / n) for n in names}
    s0 = sets[names[0]]
    print(f"# {len(names)} image sets of {s0.count} images, {s0.width}x{s0.height} px, one core")

    pairs = list(itertools.combinations(names, 2))
    if args.reference_pairs:
        pairs = pairs[: args.reference_pairs]

    # 1 + 2: reference vs fast path, pair by pair.
    ref_times, ref = [], {}
    for a, b in pairs:
        start = time.perf_counter()
        ref[(a, b)] = reference_match(sets[a], sets[b])
        ref_times.append(time.perf_counter() - start)
    config = FastConfig()

    def fast_pair(a: str, b: str) -> object:
        matcher = FastMatcher(config)
        matcher.add(matcher.prepare(sets[b]))
        return matcher.match(matcher.prepare(sets[a]))[0]

    fast_times = [time_call(lambda a=a, b=b: fast_pair(a, b), 3) for a, b in pairs[:10]]
    fast = pairwise_matches([sets[n] for n in names], config)
    index = {n: i for i, n in enumerate(names)}
    t_ref, t_fast = statistics.median(ref_times), statistics.median(fast_times)
    print("\n## Per pair of image sets (prepare both + match; median)")
    print(f"reference (full resolution, full search): {t_ref * 1000:9.1f} ms")
    print(f"fast path (default cascade)             : {t_fast * 1000:9.1f} ms")
    print(f"speed-up                                : {t_ref / t_fast:9.0f} x")

    same_shift = same_decision = 0
    d_sim, d_rot, rot_err_fast, rot_err_ref = [], [], [], []
    for a, b in pairs:
        r, f = ref[(a, b)], fast[(index[a], index[b])]
        same_shift += r.image_shift == f.image_shift
        same_decision += (r.similarity >= DEFAULT_THRESHOLD) == (f.similarity >= DEFAULT_THRESHOLD)
        d_sim.append(f.similarity - r.similarity)
        d_rot.append(abs(wrap_angle_rad(f.rotation_rad - r.rotation_rad)))
        ia, ib = info[a], info[b]
        if math.hypot(float(ia["x"]) - float(ib["x"]), float(ia["y"]) - float(ib["y"])) < 0.15:
            truth = float(ib["yaw"]) - float(ia["yaw"])
            rot_err_fast.append(abs(wrap_angle_rad(f.rotation_rad - truth)))
            rot_err_ref.append(abs(wrap_angle_rad(r.rotation_rad - truth)))
    print(f"\n## Agreement with the reference over {len(pairs)} pairs")
    print(f"same image shift      : {same_shift}/{len(pairs)}")
    print(f"same decision at {DEFAULT_THRESHOLD}: {same_decision}/{len(pairs)}")
    print(f"similarity difference : min {min(d_sim):+.4f}  max {max(d_sim):+.4f}")
    print(f"rotation difference   : max {max(d_rot):.4f} rad")
    if rot_err_fast:
        print(
            f"rotation error vs recorded yaw, {len(rot_err_fast)} same-junction pairs: "
            f"fast mean {np.mean(rot_err_fast):.4f} max {max(rot_err_fast):.4f} rad; "
            f"reference mean {np.mean(rot_err_ref):.4f} max {max(rot_err_ref):.4f} rad"
        )
    if args.write_reference:
        doc = {
            f"{a}|{b}": {
                "similarity": m.similarity,
                "image_shift": m.image_shift,
                "pixel_shift": m.pixel_shift,
                "rotation_rad": m.rotation_rad,
            }
            for (a, b), m in ref.items()
        }
        args.write_reference.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
        print(f"wrote {args.write_reference}")

    # 3: per-decision latency against synthetic databases.
    rng = np.random.default_rng(7)
    base = list(sets.values())
    print("\n## Per decision (screen all known junctions, refine the best; median of 10)")
    for size in (int(s) for s in args.sizes.split(",")):
        matcher = FastMatcher(config)
        for _ in range(size):
            matcher.add(matcher.prepare(augmented_set(base, rng)))
        queries = [sets[n] for n in names[:10]]
        times = []
        for q in queries:
            start = time.perf_counter()
            matcher.match(matcher.prepare(q))
            times.append(time.perf_counter() - start)
        print(
            f"{size:5d} known junctions: median {statistics.median(times) * 1000:7.1f} ms, "
            f"max {max(times) * 1000:7.1f} ms"
        )

    prepared = FastMatcher(config).prepare(s0)
    kept = sum(
        getattr(arr, "nbytes", 0)
        for arr in (
            prepared.template_rows,
            prepared.image_rows,
            prepared.window_norm,
            prepared.fine.spectrum,
            prepared.fine.window_norm,
        )
    )
    print(f"\n## Memory: {kept / 2**20:.2f} MiB kept per known junction")
    return 0


if __name__ == "__main__":
    sys.exit(main())
