"""How separable are same and different junctions under the robot's own lamp?

    python benchmarks/bench_lamp.py [--lamp 1.0] [--conditions noise,entrance]
        [--seeds 0] [--resolution 400] [--cache /tmp/lamp_sweeps] [--no-align-sweeps]

Renders the paper's network in placement conditions (the robot placed at each
junction of the right-hand tour, so junctions are revisited from other pipes) with
the lamp at ``--lamp`` of full strength, and with even light for comparison. For
every pair of visits, the paper's similarity (Algorithm 2, pipemap's fast path,
every offset refined) and the two-view fit's inliers, with the localizer's
illumination normalisation off and on (:mod:`localizer.illumination`). Prints, per
lighting and normalisation: the lowest similarity of a same-junction pair, the
highest of a different-junction pair, their gap, how many pairs the paper's
threshold 0.36 gets wrong, the threshold that gets fewest wrong (0.10..0.90), and
the same for two-view inliers against the verify rule's 48 (normalised: as the
localizer does under a lamp, a fit that fails at the NCC's rotation is tried again
at any rotation). The true node is read only here, to label pairs.

Rendering is the slow part (about 1 s an image at 400 px on one core); ``--cache``
keeps the sweeps for another run.
"""

from __future__ import annotations

import argparse
import itertools
import time
from pathlib import Path

import numpy as np

from pipemap.localizer import FastConfig, ImageSet, LocalizerConfig
from pipemap.localizer.illumination import normalised
from pipemap.localizer.pairwise import pairwise_matches
from pipemap.localizer.presets import PAPER_THRESHOLD
from pipemap.localizer.twoview import fit_two_view, sweep_features
from pipemap.sim.episode import Condition, Episode, SimConfig
from pipemap.sim.network import build_network
from pipemap.sim.world import CameraSpec, World


def _gray(rgb: np.ndarray) -> np.ndarray:
    weights = np.array([0.299, 0.587, 0.114], dtype=np.float32)
    out: np.ndarray = rgb.astype(np.float32) @ weights
    return out


def _sweeps(
    condition: str, seed: int, lamp: float, res: int, cache: Path | None, align: bool = True
) -> tuple:
    name = f"{condition}_s{seed}_lamp{lamp:g}_{res}px{'' if align else '_straight'}.npz"
    if cache is not None and (cache / name).exists():
        data = np.load(cache / name)
        return list(data["images"]), list(data["nodes"]), list(data["angles"])
    network = build_network("paper")
    config = SimConfig(
        Condition(condition),
        seed=seed,
        camera=CameraSpec(resolution_px=res, lamp_strength=lamp),
        align_sweeps=align,
    )
    images, nodes, angles = [], [], []
    with World(network, seed) as world:
        for visit in Episode(world, config).visits():
            images.append(np.stack([_gray(im) for im in visit.sweep.images]))
            nodes.append(visit.node)
            angles.append(visit.sweep.camera_angle_rad)
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(cache / name, images=images, nodes=nodes, angles=angles)
    return images, nodes, angles


def _table(sets: list[ImageSet], nodes: list[str], normalise: bool) -> dict[str, float]:
    if normalise:
        sets = [normalised(s) for s in sets]
    matches = pairwise_matches(sets, FastConfig(), every_offset=True)
    features = [sweep_features(s) for s in sets]
    two_view = LocalizerConfig().two_view_config
    verify = LocalizerConfig().verify_inliers
    same_sim, diff_sim, same_in, diff_in = [], [], [], []
    for i, j in itertools.combinations(range(len(sets)), 2):
        m = matches[(i, j)]
        fit = fit_two_view(features[i], features[j], two_view, m.rotation_rad)
        if normalise and (fit is None or fit.inliers < verify):
            # The localizer's rule under a lamp: fit again free of the NCC's guess.
            free = fit_two_view(features[i], features[j], two_view, None)
            if free is not None and (fit is None or free.inliers > fit.inliers):
                fit = free
        inliers = 0 if fit is None else fit.inliers
        if nodes[i] == nodes[j]:
            same_sim.append(m.similarity)
            same_in.append(inliers)
        else:
            diff_sim.append(m.similarity)
            diff_in.append(inliers)
    cuts = np.round(np.arange(0.10, 0.901, 0.01), 2)
    wrong = [sum(s < t for s in same_sim) + sum(s >= t for s in diff_sim) for t in cuts]
    return {
        "best_cut": float(cuts[int(np.argmin(wrong))]),
        "wrong_best": min(wrong),
        "same_min": min(same_sim),
        "diff_max": max(diff_sim),
        "wrong_thr": sum(s < PAPER_THRESHOLD for s in same_sim)
        + sum(s >= PAPER_THRESHOLD for s in diff_sim),
        "same_in_min": min(same_in),
        "diff_in_max": max(diff_in),
        "wrong_in": sum(n < verify for n in same_in) + sum(n >= verify for n in diff_in),
        "pairs": len(same_sim) + len(diff_sim),
        "same_pairs": len(same_sim),
        "keypoints_min": min(len(f) for f in features),
    }


def main() -> None:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--lamp", type=float, default=1.0, help="lamp strength (1.0 = full)")
    parser.add_argument("--conditions", default="noise,entrance")
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--resolution", type=int, default=400)
    parser.add_argument("--cache", type=Path, default=None)
    parser.add_argument(
        "--no-align-sweeps",
        action="store_true",
        help="start every sweep straight ahead, as in the paper (default: aligned)",
    )
    args = parser.parse_args()
    print(
        "lighting    normalise  condition  pairs(same)  same_min  diff_max  gap     "
        "wrong@0.36  best_thr(wrong)  inl_same_min  inl_diff_max  wrong@48  kp_min"
    )
    for lamp, condition, seed in itertools.product(
        (0.0, args.lamp), args.conditions.split(","), [int(s) for s in args.seeds.split(",")]
    ):
        t0 = time.process_time()
        images, nodes, angles = _sweeps(
            condition, seed, lamp, args.resolution, args.cache, not args.no_align_sweeps
        )
        sets = [
            ImageSet(im, camera_angle_rad=float(a)) for im, a in zip(images, angles, strict=True)
        ]
        for normalise in (False, True):
            r = _table(sets, nodes, normalise)
            print(
                f"{'lamp ' + format(lamp, 'g') if lamp else 'even':11s} {str(normalise):10s} "
                f"{condition}_s{seed:<3d} {r['pairs']:4.0f}({r['same_pairs']:.0f})     "
                f"{r['same_min']:.3f}     {r['diff_max']:.3f}     "
                f"{r['same_min'] - r['diff_max']:+.3f}  {r['wrong_thr']:5.0f}       "
                f"{r['best_cut']:.2f}({r['wrong_best']:.0f})       "
                f"{r['same_in_min']:5.0f}         {r['diff_in_max']:5.0f}         "
                f"{r['wrong_in']:4.0f}      {r['keypoints_min']:.0f}",
                flush=True,
            )
        print(f"#   CPU {time.process_time() - t0:.0f} s (this process)", flush=True)


if __name__ == "__main__":
    main()
