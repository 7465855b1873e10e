"""A robot off level: revisit rotation errors and decisions with and without the IMU's
levelling and the two-view fit's tilt refinement.

    python benchmarks/bench_tilt.py [--tilt-deg 3] [--conditions perfect,noise]
        [--seeds 0] [--resolution 400] [--lighting lamp] [--cache /tmp/tilt_sweeps]

Renders the paper's network in placement conditions with the robot's roll and pitch
drawn at each visit within +-``--tilt-deg`` (``SimConfig.tilt_rad``), and level for
comparison. Each run is localized visit by visit as ``pipemap map`` does (the
default rules, no probes; the lamp's normalisation when lamp-lit) three ways:
``imu``, each sweep told its IMU reading and levelled by it, no tilt refinement
needed (pipemap's defaults for a log); ``tilt``, no IMU reading (as the paper's
image sets), the tilt refinement alone; ``level``, neither. Prints per run: wrong
decisions, and the largest and median rotation error of the revisits recognised
(the decision's two-view rotation against the true heading change).
The truth is read only here, to score.
"""

from __future__ import annotations

import argparse
import itertools
import math
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from pipemap.localizer import ImageSet, Localizer, LocalizerConfig, TwoViewConfig
from pipemap.sim.episode import Condition, Episode, SimConfig
from pipemap.sim.network import build_network, wrap_rad
from pipemap.sim.world import CameraSpec, World

_GRAY = np.array([0.299, 0.587, 0.114], dtype=np.float32)


def _sweeps(args: argparse.Namespace, condition: str, seed: int, tilt_deg: float) -> dict:
    lamp = 1.0 if args.lighting == "lamp" else 0.0
    name = f"{condition}_s{seed}_tilt{tilt_deg:g}_{args.lighting}_{args.resolution}px_imu.npz"
    if args.cache is not None and (args.cache / name).exists():
        return dict(np.load(args.cache / name))
    config = SimConfig(
        Condition(condition),
        seed=seed,
        camera=CameraSpec(resolution_px=args.resolution, lamp_strength=lamp),
        tilt_rad=math.radians(tilt_deg),
    )
    keys = ("images", "nodes", "angles", "headings", "tilts", "imu")
    out: dict[str, list] = {k: [] for k in keys}
    with World(build_network("paper"), seed) as world:
        for visit in Episode(world, config).visits():
            out["images"].append(
                np.stack([im.astype(np.float32) @ _GRAY for im in visit.sweep.images])
            )
            out["nodes"].append(visit.node)
            out["angles"].append(visit.sweep.camera_angle_rad)
            out["headings"].append(visit.pose.yaw_rad)
            out["tilts"].append((visit.pose.roll_rad, visit.pose.pitch_rad))
            out["imu"].append(visit.sweep.imu_tilt_rad)
    data = {k: np.array(v) for k, v in out.items()}
    if args.cache is not None:
        args.cache.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(args.cache / name, **data)
    return data


def _run(data: dict, config: LocalizerConfig, imu: bool) -> tuple[int, list[float]]:
    localizer = Localizer(config)
    first: dict[str, int] = {}
    node_of: dict[str, int] = {}
    wrong = 0
    errors: list[float] = []
    for i, (images, node) in enumerate(zip(data["images"], data["nodes"], strict=True)):
        reading = (float(data["imu"][i][0]), float(data["imu"][i][1])) if imu else None
        query = ImageSet(images, camera_angle_rad=float(data["angles"][i]), imu_tilt_rad=reading)
        d = localizer.localize(query)
        if node in node_of:
            right = d.known and d.node == node_of[node]
            wrong += not right
            if right and d.rotation_rad is not None:
                true_turn = wrap_rad(float(data["headings"][first[node]] - data["headings"][i]))
                errors.append(abs(wrap_rad(d.rotation_rad - true_turn)))
        else:
            wrong += d.known
            node_of[node] = d.node
            first[node] = i
    return wrong, errors


def main() -> None:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tilt-deg", type=float, default=3.0)
    parser.add_argument("--conditions", default="perfect,noise")
    parser.add_argument("--seeds", default="0")
    parser.add_argument("--resolution", type=int, default=400)
    parser.add_argument("--lighting", choices=["lamp", "even"], default="lamp")
    parser.add_argument("--cache", type=Path, default=None)
    args = parser.parse_args()
    print("tilt_deg  condition     way         wrong/revisits+new  rot_err_max  rot_err_median  n")
    for tilt, condition, seed in itertools.product(
        (0.0, args.tilt_deg), args.conditions.split(","), [int(s) for s in args.seeds.split(",")]
    ):
        t0 = time.process_time()
        data = _sweeps(args, condition, seed, tilt)
        base = LocalizerConfig(active_vision=False, lamp=args.lighting == "lamp")
        for mode, imu, refine in (
            ("imu", True, True),
            ("tilt", False, True),
            ("level", False, False),
        ):
            config = replace(base, two_view_config=replace(TwoViewConfig(), tilt=refine))
            wrong, errors = _run(data, config, imu)
            err_max = max(errors) if errors else float("nan")
            err_med = float(np.median(errors)) if errors else float("nan")
            print(
                f"{tilt:<8g}  {condition}_s{seed:<5d} {mode:10s}  "
                f"{wrong:3d}/{len(data['nodes']) - 1:<3d}              {err_max:.4f}       "
                f"{err_med:.4f}          {len(errors)}",
                flush=True,
            )
        print(f"#   CPU {time.process_time() - t0:.0f} s (this process)", flush=True)


if __name__ == "__main__":
    main()
