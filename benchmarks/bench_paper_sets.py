"""``pipemap match`` on the paper's own image sets at their own size: CPU and memory.

The shared sets (``../shared/paper_imagesets``: 11 sets of six 800 x 800 JPEGs from
the paper's simulation) are matched, every pair, two ways:

* **whole process**: ``PYTHON -m pipemap match --json DIR...`` as a user runs it
  (imports, reading and decoding the images, every pair), its CPU time (user +
  system) and peak resident memory by GNU time (``/usr/bin/time``); the quickest
  of ``--repeat`` runs, and the largest peak;
* **in process**: the same interpreter loads the sets, then times
  ``pairwise_matches`` alone (one BLAS thread), with its offset ``screen`` as
  ``pipemap match`` uses it where the installation has one, the quickest of
  ``--repeat``; per pair.

Each at 800 px (the files as they are) and at 400 px (the sets reduced by area
averaging, written as PNG), with the 11 sets (55 pairs) and with 25 (the 11 and 14
mirrored, relit copies: 300 pairs). ``--python`` runs another installation (an
older commit in its own virtual environment) against the same folders; its
``pipemap`` may be one whose layers were top-level packages (``localizer``).

The yardstick is the paper's Algorithm 2 done straightforwardly: every image pair
of two sets by normalized cross-correlation over the "same" shift range at full
resolution (``pair_peak`` of this checkout on the kept top halves), CPU per pair of
sets, timed in this process on ``--reference-pairs`` pairs. ``x_algorithm2`` is that
time over the whole process's CPU per pair. The paper's own recipe resizes to a
quarter first (docs/paper_similarity.md); ``reference_quarter_ms`` times that too.

Usage: ``python benchmarks/bench_paper_sets.py [--python EXE] [--repeat N]``; prints
one JSON document.
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SETS = ROOT.parent / "shared" / "paper_imagesets"
#: Variables that size the BLAS thread pool: left to the command in the whole process.
#: GNU time: CPU and peak memory of the command alone.
TIME = "/usr/bin/time"
BLAS_VARS = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")

#: Run by the measured interpreter: the in-process time of every pair.
IN_PROCESS = """
import json, os, sys, time
try:
    from pipemap.imagesets import load_image_sets
except ImportError:  # layers as top-level packages
    from pipemap.folders import load_image_sets
try:
    from pipemap.localizer import pairwise_matches
except ImportError:
    from localizer import pairwise_matches
import inspect
sets = load_image_sets(sys.argv[2:])
# As ``pipemap match`` calls it: with the offset screen where the installation has one.
screened = "screen" in inspect.signature(pairwise_matches).parameters
options = {"screen": True} if screened else {}
best = float("inf")
for _ in range(int(sys.argv[1])):
    start = time.process_time()
    matches = pairwise_matches(sets, **options)
    best = min(best, time.process_time() - start)
print(json.dumps({"cpu_s": best, "pairs": len(matches)}))
"""


def image_files(folder: Path) -> list[Path]:
    return sorted(folder.glob("camera_image*"), key=lambda p: int(p.stem[len("camera_image") :]))


def write_sets(sets: Path, out: Path, px: int | None, extra: int) -> list[str]:
    """The shared sets (reduced to ``px`` if given) and ``extra`` altered copies."""
    names = sorted(p.name for p in sets.iterdir() if p.is_dir())
    grey = {
        n: [cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in image_files(sets / n)] for n in names
    }
    if px is not None:
        grey = {
            n: [cv2.resize(im, (px, px), interpolation=cv2.INTER_AREA) for im in images]
            for n, images in grey.items()
        }
    dirs = [str(sets / n) for n in names] if px is None else []
    rng = np.random.default_rng(7)
    todo = [(n, grey[n], False) for n in names] if px is not None else []
    for i in range(extra):
        todo.append((f"copy{i:02d}", grey[names[i % len(names)]], True))
    for name, images, altered in todo:
        folder = out / name
        folder.mkdir(parents=True)
        if altered:  # the junction seen in a mirror, under another light
            gain, offset = rng.uniform(0.8, 1.2), rng.uniform(-20.0, 20.0)
            images = [
                np.clip(im[:, ::-1].astype(np.float64) * gain + offset, 0, 255).astype(np.uint8)
                for im in reversed(images)
            ]
        for j, image in enumerate(images):
            cv2.imwrite(str(folder / f"camera_image{j + 1}.png"), image)
        dirs.append(str(folder))
    return dirs


def whole_process(python: str, dirs: list[str], repeat: int) -> dict[str, object]:
    """CPU seconds (quickest run) and peak memory (largest) of ``pipemap match``,
    as GNU time reports them (a child forked from this process would count this
    process's memory in its peak until it runs the command)."""
    env = {k: v for k, v in os.environ.items() if k not in BLAS_VARS}
    cpu, peak = [], []
    with tempfile.TemporaryDirectory() as tmp:
        report = Path(tmp) / "time.txt"
        for _ in range(repeat):
            subprocess.run(
                [TIME, "-f", "%U %S %M", "-o", str(report), python, "-m", "pipemap", "match"]
                + ["--json", *dirs],
                stdout=subprocess.DEVNULL,
                env=env,
                cwd=tmp,  # never the checkout's own folders
                check=True,
            )
            user, system, kib = report.read_text().split()[-3:]
            cpu.append(float(user) + float(system))
            peak.append(int(kib) / 1024.0)
    return {
        "cpu_s": round(min(cpu), 3),
        "cpu_s_runs": [round(c, 3) for c in cpu],
        "peak_mib": round(max(peak), 1),
    }


def in_process(python: str, dirs: list[str], repeat: int) -> dict[str, float]:
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    out = subprocess.run(
        [python, "-c", IN_PROCESS, str(repeat), *dirs],
        check=True,
        capture_output=True,
        text=True,
        env=env,
        cwd=tempfile.gettempdir(),
    ).stdout
    result = json.loads(out.strip().splitlines()[-1])
    return {"cpu_ms_per_pair": round(1000.0 * result["cpu_s"] / result["pairs"], 3)}


def algorithm2_ms(sets: Path, pairs: int) -> dict[str, float]:
    """The yardstick: CPU ms per pair of sets, full resolution and the quarter scale."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    sys.path.insert(0, str(ROOT))
    from pipemap.imagesets import load_image_set
    from pipemap.localizer import reference_match
    from pipemap.localizer.similarity import pair_peak

    names = sorted(p.name for p in sets.iterdir() if p.is_dir())
    full, quarter = [], []
    for a, b in itertools.islice(itertools.combinations(names, 2), pairs):
        sa, sb = load_image_set(sets / a), load_image_set(sets / b)
        ca, cb = sa.cropped().astype(np.float64), sb.cropped().astype(np.float64)
        start = time.process_time()
        for j, m in itertools.product(range(sa.count), range(sb.count)):
            pair_peak(ca[j], cb[m])
        full.append(time.process_time() - start)
        start = time.process_time()
        reference_match(sa, sb)
        quarter.append(time.process_time() - start)
    return {
        "reference_full_ms": round(1000.0 * statistics.median(full), 1),
        "reference_quarter_ms": round(1000.0 * statistics.median(quarter), 1),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", type=Path, default=DEFAULT_SETS)
    parser.add_argument("--python", default=sys.executable, help="interpreter to measure")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each case (3)")
    parser.add_argument("--reference-pairs", type=int, default=1, help="pairs timed (1)")
    parser.add_argument("--extra", type=int, default=14, help="altered copies (14: 25 sets)")
    args = parser.parse_args()
    doc: dict[str, object] = {"python": args.python, "repeat": args.repeat}
    doc.update(algorithm2_ms(args.sets, args.reference_pairs))
    cases: dict[str, object] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for px in (800, 400):
            for extra in (0, args.extra):
                folder = Path(tmp) / f"{px}_{extra}"
                dirs = write_sets(args.sets, folder, None if px == 800 else px, extra)
                pairs = len(dirs) * (len(dirs) - 1) // 2
                case: dict[str, object] = {"px": px, "sets": len(dirs), "pairs": pairs}
                case["whole_process"] = whole_process(args.python, dirs, args.repeat)
                case["in_process"] = in_process(args.python, dirs, args.repeat)
                per_pair_ms = 1000.0 * case["whole_process"]["cpu_s"] / pairs  # type: ignore[index]
                case["whole_process_ms_per_pair"] = round(per_pair_ms, 2)
                if px == 800:  # the yardstick's size
                    full_ms = float(doc["reference_full_ms"])  # type: ignore[arg-type]
                    case["x_algorithm2"] = round(full_ms / per_pair_ms)
                cases[f"{px}px_{len(dirs)}sets"] = case
    doc["cases"] = cases
    print(json.dumps(doc, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
