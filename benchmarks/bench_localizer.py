"""Benchmark of the localizer on the paper's image sets: speed, agreement, memory.

Prints, on one core (BLAS and FFT threads pinned to 1 before numpy loads):

1. per-pair time of the reference and of the fast path at full resolution;
2. agreement of the fast path with the reference over every pair of the shared
   sets (image shift, known/unknown decision, similarity, rotation);
3. per-decision latency against databases of 1, 10, 100, 1000 and 10 000 known junctions,
   synthetic ones made from augmented copies of the shared images;
4. memory kept per known junction;

5. ``pipemap match`` end to end on 25 sets.

Usage: ``python benchmarks/bench_localizer.py [--sets DIR] [--reference-pairs K]
[--write-reference FILE]``, or ``--json [--repeat N]`` for the decision benchmark
alone: the shared sets at 400 px as queries, decided at the defaults (two-view check
included) by a localizer that knows 10, 100, 1000 and 10 000 junctions (augmented
copies; the 10 000 repeat the first 1000; ``--no-index`` screens every one of them),
one core; wall and CPU time per decision (the median over queries of each query's
quickest of N tries, 5 by default), the same with the refinement cache emptied
before each try (``decision_cold_ms``), and the memory kept per known junction (also as
a lamp-lit camera's localizer keeps 100 of them, ``memory_per_junction_lamp_kib``),
array by array (``memory_parts_kib``; ``--px`` sets the sets' size, 400 by default).
Agreement is measured against the stored reference
values of all 55 pairs (``tests/localizer/data/paper_reference.json``, which a test
keeps current); the reference is timed on K pairs (default 3). ``--write-reference``
recomputes and writes all 55 (a few minutes).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import itertools  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import pickle  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

cv2.setNumThreads(1)

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pipemap.allocator import keep_freed_memory  # noqa: E402
from pipemap.imagesets import load_image_set, read_info  # noqa: E402
from pipemap.localizer import (  # noqa: E402
    DEFAULT_THRESHOLD,
    FastConfig,
    FastMatcher,
    ImageSet,
    Localizer,
    LocalizerConfig,
    fit_two_view,
    pairwise_matches,
    prepare,
    reference_match,
    wrap_angle_rad,
)

DEFAULT_SETS = ROOT.parent / "shared" / "paper_imagesets"
from pipemap.localizer.fastmatch import _FINE_CACHE  # noqa: E402
from pipemap.localizer.illumination import normalised  # noqa: E402
from pipemap.localizer.twoview import StoredFeatures, stored_features  # noqa: E402

REFERENCE_VALUES = ROOT / "tests" / "localizer" / "data" / "paper_reference.json"


def augmented_set(base: list[ImageSet], rng: np.random.Generator) -> ImageSet:
    """A plausible distractor that is no junction of ``base``: images of one or two
    base sets, mirrored left to right (always: ORB's descriptors are not
    mirror-invariant, so a mirrored view matches its original no better than a
    different junction would), rolled, sometimes in reverse order, relit."""
    first = base[int(rng.integers(len(base)))].images
    second = base[int(rng.integers(len(base)))].images
    n = first.shape[0]
    take = rng.random(n) < 0.5
    images = np.where(take[:, None, None], first, second)[:, :, ::-1]
    images = np.roll(images, int(rng.integers(n)), axis=0)
    if rng.random() < 0.5:
        images = images[::-1]  # the sweep turning the other way
    gain = rng.uniform(0.7, 1.3)
    offset = rng.uniform(-20, 20)
    shift = int(rng.integers(-40, 41))
    images = np.roll(images, shift, axis=2) * gain + offset
    images = images + rng.normal(0.0, 3.0, images.shape)
    return ImageSet(np.rint(np.clip(images, 0, 255)).astype(np.float32))


def resized(image_set: ImageSet, px: int) -> ImageSet:
    """The set at ``px`` x ``px`` (area averaging, rounded to 8 bits as a camera gives)."""
    images = [cv2.resize(im, (px, px), interpolation=cv2.INTER_AREA) for im in image_set.images]
    return ImageSet(np.rint(np.stack(images)), fov_rad=image_set.fov_rad)


#: Distractors drawn afresh; a larger database repeats them (see ``_distractor_localizer``).
UNIQUE_DISTRACTORS = 1000


def _distractor_localizer(
    queries: list[ImageSet], size: int, rng: np.random.Generator, lamp: bool = False
) -> tuple[Localizer, list[StoredFeatures]]:
    """A localizer that knows ``size`` distractors, seeded as the localizer itself
    does for a new junction (prepare once, keypoints once) without deciding each;
    and the distractors' keypoints. With ``lamp``, as a lamp-lit camera's localizer
    sees them: each divided by its illumination first. Beyond
    ``UNIQUE_DISTRACTORS`` the distractors repeat in order (each repeat is a junction
    of its own to the localizer, with its own screening rows and map node): drawing
    and preparing 10 000 would take this machine most of an hour."""
    localizer = Localizer(LocalizerConfig(lamp=lamp))
    drawn: list[tuple[object, StoredFeatures]] = []
    for k in range(size):
        if k < UNIQUE_DISTRACTORS:
            distractor = augmented_set(queries, rng)
            if lamp:
                distractor = normalised(distractor, localizer.config.illumination)
            config = localizer.config.two_view_config
            drawn.append(
                (localizer._matcher.prepare(distractor), stored_features(distractor, config))
            )
        prepared, features = drawn[k % UNIQUE_DISTRACTORS]
        localizer._matcher.add(prepared)  # type: ignore[arg-type]
        localizer._features.append(features)
        localizer.map.visit(len(localizer._features) - 1)
    return localizer, list(localizer._features)


def _kept_per_junction_kib(localizer: Localizer) -> float:
    """What each known junction keeps: the matcher's arrays and compact images, and
    its keypoints (KiB). The distractors are built without the closer look's
    keypoints (``localizer.closer``), which ``bench_closer_look.py`` measures."""
    held = localizer._matcher.kept_bytes() + sum(f.nbytes for f in localizer._features)
    return held / localizer.known_count / 1024


def _kept_parts_kib(localizer: Localizer) -> dict[str, float]:
    """What each known junction keeps, array by array (KiB a junction): the screen's
    rows and window norms, the refinement's compact images, the index's descriptor,
    and the keypoints' descriptors, positions and counts per image."""
    matcher = localizer._matcher
    known = localizer.known_count
    arrays = matcher._screening_arrays()
    rows, norms = (0, 0) if arrays is None else (arrays[0].nbytes, arrays[1].nbytes)
    fine = sum(s.fine_images.values.nbytes for s in matcher._sets if s.fine_images is not None)
    features = localizer._features
    parts = {
        "screen_rows": rows,
        "screen_norms": norms,
        "refine_images": fine,
        "index": matcher._index.nbytes(),
        "keypoint_descriptors": sum(f.descriptors.nbytes for f in features),
        "keypoint_positions": sum(f.points.nbytes for f in features),
        "keypoint_counts": sum(f.per_image.nbytes for f in features),
    }
    kib = {name: round(size / known / 1024, 2) for name, size in parts.items()}
    kib["keypoints_per_junction"] = round(sum(len(f) for f in features) / known, 1)
    return kib


def _forget_after(localizer: Localizer, count: int, saved: bytes) -> None:
    """Undo the decisions since the localizer knew ``count`` junctions (the index
    only grows by appending, so truncating it is exact); ``saved`` is the map then,
    pickled (a tenth of the time a deep copy of 10 000 nodes took)."""
    matcher = localizer._matcher
    del matcher._sets[count:]
    matcher._index.truncate(count)
    for key in [k for k in matcher._fine_cache if k >= count]:
        del matcher._fine_cache[key]
    del localizer._features[count:]
    localizer._closer.forget(count)
    localizer.map = pickle.loads(saved)


def decision_benchmark(
    sets: dict[str, ImageSet],
    sizes: list[int],
    px: int,
    check: bool = False,
    repeat: int = 1,
    index: bool = True,
) -> dict:  # type: ignore[type-arg]
    """Decisions at the defaults against databases of ``sizes`` known junctions.

    Every query is decided against the distractors alone (the database is reset
    after each), so each decision is a new junction's: the two-view check tries all
    its candidates, the slowest case. ``known`` counts queries decided known (a
    distractor taken for a query's junction; must be 0). Each query is decided
    ``repeat`` times and its quickest time kept (as ``timeit`` advises: the others
    measure what else the machine was doing); the median is over the queries.

    ``decision_ms`` is measured with the refinement cache as the query's previous
    try left it: its candidates' spectra at hand. ``decision_cold_ms`` empties the
    cache before each try, so every candidate's spectra are rebuilt from its compact
    images, as most decisions of a real run do (replaying the 100-junction log, 173
    of 206 decisions rebuilt at least one, 1.3 on average).
    ``rebuilds_per_decision`` counts them in each mode. With
    ``check``, every query is also fitted against every distractor (no rotation
    guess, so every image against every image), and the most inliers any pair
    reaches is reported.
    """
    queries = [resized(s, px) for s in sets.values()]
    rng = np.random.default_rng(7)
    decision_ms: dict[str, float] = {}
    cold_ms: dict[str, float] = {}
    cpu_ms: dict[str, float] = {}
    rebuilds = {"warm": 0, "cold": 0}
    known = 0
    most_inliers = 0
    memory = 0.0
    parts: dict[str, float] = {}
    for size in sizes:
        localizer, distractors = _distractor_localizer(queries, size, rng)
        if not index:  # every junction screened, however many (as below INDEX_ABOVE)
            localizer._matcher.index_above = sys.maxsize
        saved = pickle.dumps(localizer.map, protocol=pickle.HIGHEST_PROTOCOL)
        walls, cpus, colds = [], [], []
        for query in queries:
            tries, cold_tries, decided_known = [], [], False
            for cold in [True] * repeat + [False] * repeat:
                if cold:
                    localizer._matcher._fine_cache.clear()
                cached = set(localizer._matcher._fine_cache)
                wall, cpu = time.perf_counter(), time.process_time()
                decision = localizer.localize(query)
                elapsed = (time.perf_counter() - wall, time.process_time() - cpu)
                (cold_tries if cold else tries).append(elapsed)
                rebuilds["cold" if cold else "warm"] += len(
                    set(localizer._matcher._fine_cache) - cached
                )
                decided_known |= decision.known
                _forget_after(localizer, size, saved)
            known += decided_known
            walls.append(min(t[0] for t in tries))
            cpus.append(min(t[1] for t in tries))
            colds.append(min(t[0] for t in cold_tries))
        decision_ms[str(size)] = round(statistics.median(walls) * 1000, 2)
        cold_ms[str(size)] = round(statistics.median(colds) * 1000, 2)
        cpu_ms[str(size)] = round(statistics.median(cpus) * 1000, 2)
        memory = _kept_per_junction_kib(localizer)
        parts = _kept_parts_kib(localizer)
        # Beside what each junction keeps: the refinement cache's few sets, a fixed
        # sum (the most it holds: its size in sets times what each of the last held).
        held = localizer._matcher._fine_cache
        cache = localizer._matcher.cache_bytes() / 1024 / max(1, len(held)) * _FINE_CACHE
        if check:
            config = localizer.config.two_view_config
            for query in queries:
                features = stored_features(query, config).features()
                for stored in distractors:
                    fit = fit_two_view(features, stored.features(), config)
                    most_inliers = max(most_inliers, 0 if fit is None else fit.inliers)
    result = {
        "resolution_px": px,
        "decision_ms": decision_ms,
        "decision_cpu_ms": cpu_ms,
        "decision_cold_ms": cold_ms,
        "rebuilds_per_decision": {
            mode: round(count / (len(sizes) * len(queries) * repeat), 2)
            for mode, count in rebuilds.items()
        },
        "memory_per_junction_kib": round(memory, 1),
        "memory_parts_kib": parts,
        # The same junctions as a lamp-lit camera's localizer keeps them (normalised
        # images: their refinement images on a 1/256 grey-level grid).
        "memory_per_junction_lamp_kib": round(
            _kept_per_junction_kib(_distractor_localizer(queries, 100, rng, lamp=True)[0]), 1
        ),
        "refine_cache_kib": round(cache, 1),
        "two_view": True,
        "index": index,
        "queries": len(queries),
        "repeat": repeat,
        "known": known,
    }
    if check:
        result["distractor_max_inliers"] = most_inliers
    return result


def time_call(fn, repeat: int) -> float:  # type: ignore[no-untyped-def]
    """Median wall time of ``fn()`` in seconds."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _same_junction(a: dict[str, str], b: dict[str, str]) -> bool:
    return math.hypot(float(a["x"]) - float(b["x"]), float(a["y"]) - float(b["y"])) < 0.15


def _agreement(title: str, got: dict, ref: dict, info: dict) -> None:  # type: ignore[type-arg]
    same = [k for k in ref if _same_junction(info[k[0]], info[k[1]])]
    other = [k for k in ref if k not in same]
    decisions = sum(
        (got[k].similarity >= DEFAULT_THRESHOLD) == (ref[k]["similarity"] >= DEFAULT_THRESHOLD)
        for k in ref
    )
    d_sim = [got[k].similarity - ref[k]["similarity"] for k in ref]
    d_rot = [abs(wrap_angle_rad(got[k].rotation_rad - ref[k]["rotation_rad"])) for k in same]
    print(f"\n## Agreement with the reference, {title}")
    print(f"same decision at {DEFAULT_THRESHOLD}      : {decisions}/{len(ref)}")
    print(f"similarity difference      : min {min(d_sim):+.4f}  max {max(d_sim):+.4f}")
    shift_same = sum(got[k].image_shift == ref[k]["image_shift"] for k in same)
    shift_other = sum(got[k].image_shift == ref[k]["image_shift"] for k in other)
    print(
        f"same image shift           : {shift_same}/{len(same)} same-junction pairs, "
        f"{shift_other}/{len(other)} different-junction pairs (offset is noise there)"
    )
    print(f"rotation difference        : max {max(d_rot):.4f} rad over same-junction pairs")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=Path, default=DEFAULT_SETS)
    parser.add_argument("--reference-pairs", type=int, default=3, help="pairs to time (3)")
    parser.add_argument("--reference-values", type=Path, default=REFERENCE_VALUES)
    parser.add_argument(
        "--write-reference", type=Path, default=None, help="recompute all pairs (minutes)"
    )
    parser.add_argument("--sizes", default="1,10,100,1000")
    parser.add_argument("--json", action="store_true", help="decision benchmark only, as JSON")
    parser.add_argument("--px", type=int, default=400, help="image size of --json (400)")
    parser.add_argument(
        "--repeat",
        type=int,
        default=5,
        help="with --json: decide each query N times, keep its best (5)",
    )
    parser.add_argument(
        "--no-index",
        action="store_true",
        help="with --json: screen every known junction, however many (no shortlist)",
    )
    parser.add_argument(
        "--check-distractors",
        action="store_true",
        help="with --json: fit every query against every distractor (minutes)",
    )
    args = parser.parse_args()
    allocator_set_up = keep_freed_memory()  # as pipemap's commands run (pipemap.allocator)
    if args.json:
        names = sorted(p.name for p in args.sets.iterdir() if p.is_dir())
        sets = {n: load_image_set(args.sets / n) for n in names}
        sizes = (
            [10, 100, 1000, 10000]
            if args.sizes == "1,10,100,1000"
            else [int(x) for x in args.sizes.split(",")]
        )
        result = decision_benchmark(
            sets, sizes, args.px, args.check_distractors, args.repeat, not args.no_index
        )
        result["allocator_set_up"] = allocator_set_up
        print(json.dumps(result, indent=2))
        return 0

    names = sorted(p.name for p in args.sets.iterdir() if p.is_dir())
    sets = {n: load_image_set(args.sets / n) for n in names}
    info = {n: read_info(args.sets / n) for n in names}
    s0 = sets[names[0]]
    print(f"# {len(names)} image sets of {s0.count} images, {s0.width}x{s0.height} px, one core")
    pairs = list(itertools.combinations(names, 2))

    # 1: time per pair.
    timed = pairs[: args.reference_pairs] if not args.write_reference else pairs
    ref_times, computed = [], {}
    for a, b in timed:
        start = time.perf_counter()
        m = reference_match(sets[a], sets[b])
        ref_times.append(time.perf_counter() - start)
        computed[(a, b)] = {
            "similarity": m.similarity,
            "image_shift": m.image_shift,
            "pixel_shift": m.pixel_shift,
            "rotation_rad": m.rotation_rad,
        }
    if args.write_reference:
        doc = {f"{a}|{b}": v for (a, b), v in computed.items()}
        args.write_reference.write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
        print(f"wrote {args.write_reference}")
    config = FastConfig()
    prepared = {n: prepare(sets[n], config) for n in names}

    def match_prepared(a: str, b: str) -> object:
        matcher = FastMatcher(config)
        matcher.add(prepared[b])
        return matcher.match(prepared[a])[0]

    t_ref = statistics.median(ref_times)
    t_prep = statistics.median(time_call(lambda n=n: prepare(sets[n], config), 3) for n in names)
    t_match = statistics.median(
        time_call(lambda a=a, b=b: match_prepared(a, b), 5) for a, b in pairs[:10]
    )
    print(f"\n## Per pair of image sets (median; reference timed on {len(timed)} pairs)")
    print(f"reference, full resolution and search    : {t_ref * 1000:8.1f} ms")
    print(
        f"fast path, match two prepared sets       : {t_match * 1000:8.1f} ms "
        f"({t_ref / t_match:.0f}x)"
    )
    print(f"fast path, prepare one set (once per set): {t_prep * 1000:8.1f} ms")
    print(
        f"fast path, prepare both and match        : {(2 * t_prep + t_match) * 1000:8.1f} ms "
        f"({t_ref / (2 * t_prep + t_match):.0f}x)"
    )

    # 2: agreement with the stored reference values.
    stored = json.loads(args.reference_values.read_text())
    ref = {tuple(k.split("|")): v for k, v in stored.items()}
    index = {n: i for i, n in enumerate(names)}
    every = pairwise_matches([sets[n] for n in names], config, every_offset=True)
    _agreement(
        f"all {len(ref)} pairs, `pipemap match --every-offset`",
        {k: every[(index[k[0]], index[k[1]])] for k in ref},
        ref,
        info,
    )
    _agreement(
        f"all {len(ref)} pairs, `pipemap match` and the localizer "
        "(best junction refined at every offset)",
        {k: match_prepared(*k) for k in ref},
        ref,
        info,
    )
    errors = {"paper": [], "pinhole": []}  # type: ignore[var-annotated]
    for a, b in pairs:
        if _same_junction(info[a], info[b]):
            m = every[(index[a], index[b])]
            truth = float(info[b]["yaw"]) - float(info[a]["yaw"])
            errors["paper"].append(abs(wrap_angle_rad(m.rotation_rad - truth)))
            errors["pinhole"].append(abs(wrap_angle_rad(m.rotation_pinhole_rad - truth)))
    print(
        f"\n## Rotation error against the recorded yaw, {len(errors['paper'])} same-junction pairs"
    )
    for name, errs in errors.items():
        print(f"{name:8s}: mean {np.mean(errs):.4f} rad, max {max(errs):.4f} rad")

    # 3: per-decision latency against synthetic databases.
    rng = np.random.default_rng(7)
    base = list(sets.values())
    print("\n## Per decision: prepare the query, screen all known junctions, refine the best")
    print("(median of 10 queries; prepare and match split)")
    for size in (int(s) for s in args.sizes.split(",")):
        matcher = FastMatcher(config)
        for _ in range(size):
            matcher.add(matcher.prepare(augmented_set(base, rng)))
        preps, matches, totals = [], [], []
        for q in (sets[n] for n in names[:10]):
            start = time.perf_counter()
            pq = matcher.prepare(q)
            mid = time.perf_counter()
            matcher.match(pq)
            end = time.perf_counter()
            preps.append(mid - start)
            matches.append(end - mid)
            totals.append(end - start)
        print(
            f"{size:5d} known junctions: {statistics.median(totals) * 1000:7.1f} ms "
            f"(prepare {statistics.median(preps) * 1000:5.1f}, "
            f"match {statistics.median(matches) * 1000:6.1f}; max {max(totals) * 1000:6.1f})"
        )

    held = FastMatcher(config)
    for n in names:
        held.add(prepared[n])
    kept = held.kept_bytes() / len(names)
    print(f"\n## Memory: {kept / 2**10:.1f} KiB of similarity data kept per known junction")

    # 4: the CLI end to end on 25 sets written to disk (11 shared + 14 augmented).
    with tempfile.TemporaryDirectory() as tmp:
        dirs = [str(args.sets / n) for n in names]
        for i in range(25 - len(dirs)):
            folder = Path(tmp) / f"aug{i:02d}"
            folder.mkdir()
            for j, image in enumerate(augmented_set(base, rng).images):
                cv2.imwrite(str(folder / f"camera_image{j + 1}.png"), image.astype(np.uint8))
            dirs.append(str(folder))
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        start = time.perf_counter()
        subprocess.run(
            [sys.executable, "-m", "pipemap", "match", "--json", *dirs],
            check=True,
            env=env,
            stdout=subprocess.DEVNULL,
        )
        wall = time.perf_counter() - start
    print(
        f"\n## `pipemap match` on 25 sets ({len(dirs) * (len(dirs) - 1) // 2} pairs), "
        f"end to end: {wall:.1f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
