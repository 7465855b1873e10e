"""``pipemap sim``: run an episode and save every sweep in the paper's folder layout.

``DIR/0001``, ``DIR/0002``, ... in visit order, each ``camera_image1..N.png`` plus
``info.txt`` with the camera pose at the sweep start and the true node, so that
``pipemap map DIR/*`` maps the run. A sweep that did not start straight ahead has
a ``sweep.txt`` with its camera angle (see :mod:`pipemap.imagesets`). In the
``active`` condition the localizer runs online and its probe sweeps go to
``DIR/NNNN/probes/<kind>/`` (inside the visit's folder, so they are not visits
themselves).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
import shutil
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any, TextIO

import numpy as np

from pipemap.cli.outputs import output_folder
from pipemap.cli.run_settings import check_condition_flags, explore_policy
from pipemap.cli.slow import world_notice
from pipemap.errors import InputError, WriteError
from pipemap.imagesets import RobotNotes, write_image_set

if TYPE_CHECKING:  # the simulator loads lazily: pipemap --help stays instant
    from pipemap.sim.episode import Condition
    from pipemap.sim.motor_faults import MotorFault
    from pipemap.sim.network import Network
    from pipemap.sim.obstacles import Obstacle

__all__ = ["run_sim"]

#: The folders of one run's sweeps: ``0001``, ``0002``, ...
_SWEEP_FOLDER = re.compile(r"\d{4}")


def _info(pose: object, node: str) -> dict[str, str]:
    fields = ("x_m", "y_m", "z_m", "roll_rad", "pitch_rad", "yaw_rad")
    keys = ("x", "y", "z", "roll", "pitch", "yaw")
    info = {"cam_joint_pos": ""}
    for key, name in zip(keys, fields, strict=True):
        info[key] = repr(float(getattr(pose, name)))
    info["node"] = node
    return info


def _gray_set(images: np.ndarray, fov_rad: float, camera_angle_rad: float) -> Any:
    from pipemap.recorder.online import gray_set

    return gray_set(images, fov_rad, camera_angle_rad)


def _earlier_sweeps(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.is_dir() and _SWEEP_FOLDER.fullmatch(p.name))


def _clear_earlier_sweeps(target: Path) -> None:
    """Make the folder; with ``--force`` an earlier run's sweep folders go first, so
    that ``pipemap map DIR/*`` sees this run's alone (other files are left)."""
    try:
        target.mkdir(parents=True, exist_ok=True)
        for folder in _earlier_sweeps(target):
            shutil.rmtree(folder)
    except OSError as exc:
        raise WriteError(f"--save-sweeps {target}: {exc.strerror or exc}") from None


def run_sim(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Validate, build the world, run the episode, write the sweeps, print a summary."""
    from pipemap.sim.episode import Condition, Episode, SimConfig
    from pipemap.sim.lookalike import choose_looks
    from pipemap.sim.network import build_network
    from pipemap.sim.world import CameraSpec, World
    from pipemap.sim.world_budget import check_world_fits

    check_condition_flags(args)
    target = output_folder(args.save_sweeps, "--save-sweeps", args.force)
    network = build_network(args.network, seed=args.seed)
    check_world_fits(network, args.network)
    condition = Condition(args.condition)
    if args.start is not None and args.start not in network.labels:
        raise InputError(
            f"--start {args.start}: no such node in {args.network} ({', '.join(network.labels)})"
        )
    lamp = 1.0 if args.lighting == "lamp" else 0.0
    camera = CameraSpec(resolution_px=args.resolution, lamp_strength=lamp)
    config = SimConfig(
        condition=condition,
        seed=args.seed,
        camera=camera,
        images_per_sweep=args.images,
        align_sweeps=args.align_sweeps,
        tilt_rad=math.radians(args.tilt_deg),
    )
    deposits, faults = _real_conditions(args, network, condition)
    _clear_earlier_sweeps(target)
    if condition is Condition.AUTONOMOUS:
        return _run_autonomous(args, network, camera, target, out, err, deposits, faults)
    looks = choose_looks(network, args.alike, args.seed)
    with world_notice(err, args.network, network):
        world = World(network, seed=args.seed, looks=looks)
    with world:
        episode = Episode(world, config, start=args.start)
        localizer = None
        if condition is Condition.ACTIVE:
            from pipemap.localizer import Localizer, LocalizerConfig

            # It asks for probes as the recorder's would: normalising lamp-lit sweeps.
            localizer = Localizer(LocalizerConfig().for_camera(camera.lamp_strength > 0.0))
        sweeps = 0
        for visit in episode.visits():
            folder = target / f"{visit.index + 1:04d}"
            sweep = visit.sweep
            info = _info(visit.sweep_truth.camera_pose, visit.node)
            lit = RobotNotes(lighting=args.lighting)
            write_image_set(folder, sweep.images, info, sweep.camera_angle_rad, lit)
            sweeps += 1
            if localizer is not None:
                sweeps += _localize_with_probes(localizer, visit, folder, camera.fov_rad)
    tour = episode.tour
    distance = sum(
        network.length_m(a.node, b.node) for a, b in zip(tour.visits, tour.visits[1:], strict=False)
    )
    status = "complete" if tour.complete else "incomplete"
    out.write(
        f"network {args.network} from {tour.visits[0].node}, condition {condition.value}: "
        f"{len(tour.visits)} visits of {len(tour.covered_nodes)}/{len(network.nodes)} nodes, "
        f"{distance:.2f} m, {sweeps} sweeps, {status}\n"
    )
    return 0 if tour.complete else 1


def _real_conditions(
    args: argparse.Namespace, network: Network, condition: Condition
) -> tuple[tuple[Obstacle, ...], tuple[MotorFault, ...]]:
    """The floor deposits of ``--obstacles`` and the motor cut-outs of
    ``--motor-faults`` (autonomous only: :func:`check_condition_flags`), checked before
    any work."""
    from pipemap.errors import SimError
    from pipemap.sim.motor_faults import draw_motor_faults
    from pipemap.sim.obstacles import place_obstacles

    try:
        deposits = place_obstacles(network, args.obstacles, args.seed)
    except SimError as error:
        raise InputError(f"--obstacles {args.obstacles}: {error}") from None
    return deposits, draw_motor_faults(network, args.motor_faults, args.seed)


def _conditions(deposits: tuple[Obstacle, ...], faults: tuple[MotorFault, ...]) -> str:
    """``N deposits``, ``N motor cut-outs``, or both, for the run's summary."""
    parts = [f"{len(deposits)} deposits"] if deposits else []
    parts += [f"{len(faults)} motor cut-outs"] if faults else []
    return ", ".join(parts)


def _run_autonomous(  # type: ignore[no-untyped-def]
    args, network, camera, target: Path, out: TextIO, err: TextIO, deposits=(), faults=()
) -> int:
    """The full exploration by the sensor-driven controller; sweeps are kept whatever
    ends it. With ``--explore map`` the localizer runs online and the robot explores
    its map; each sweep's ``sweep.txt`` then holds its exits and departure too."""
    from pipemap.localizer import Localizer, LocalizerConfig
    from pipemap.recorder.online import Explore, OnlineLocalizer, make_policy
    from pipemap.sim.controller import ExplorerConfig, RunStatus, autonomous_run
    from pipemap.sim.lookalike import choose_looks
    from pipemap.sim.stream import NodeDeparture, NodeExits, SimRecord
    from pipemap.sim.world import World

    explore = Explore(explore_policy(args))
    online = OnlineLocalizer(
        Localizer(LocalizerConfig().for_camera(camera.lamp_strength > 0.0)), camera.fov_rad
    )
    notes: dict[int, RobotNotes] = {}

    def sink(record: SimRecord) -> None:
        if explore is Explore.MAP:
            online(record)
        if isinstance(record, NodeExits):
            notes[record.visit_id] = RobotNotes(record.exits_rad, None, record.odometer_m)
        elif isinstance(record, NodeDeparture) and record.visit_id in notes:
            n = notes[record.visit_id]
            notes[record.visit_id] = RobotNotes(n.exits_rad, record.exit_rad, n.odometer_m)

    looks = choose_looks(network, args.alike, args.seed)
    with world_notice(err, args.network, network):
        world = World(network, seed=args.seed, obstacles=deposits, looks=looks)
    with world:
        config = ExplorerConfig(
            images_per_sweep=args.images,
            align_sweeps=args.align_sweeps,
            tilt_rad=math.radians(args.tilt_deg),
        )
        policy = make_policy(explore, online, config.start_radius_m, config.drift_per_m)
        result = autonomous_run(
            world,
            camera,
            args.seed,
            start=args.start,
            config=config,
            sink=sink,
            policy=policy,
            motor_faults=faults,
        )
    for index, (sweep, truth) in enumerate(
        zip(result.sweeps, result.sweep_truths, strict=True), start=1
    ):
        info = _info(truth.camera_pose, truth.node)
        folder = target / f"{index:04d}"
        noted = dataclasses.replace(notes.get(index, RobotNotes()), lighting=args.lighting)
        write_image_set(folder, sweep.images, info, sweep.camera_angle_rad, noted)
    visited = {s.node for s in result.sweep_truths} - {"?"}
    path = [s.node for s in result.sweep_truths]
    pipes = {frozenset((p.a, p.b)) for p in network.pipes}
    driven = len({frozenset(ab) for ab in zip(path, path[1:], strict=False)} & pipes)
    # The robot believes it is done; the simulator knows whether it covered the network.
    covered = len(visited) == len(network.nodes) and driven == len(pipes)
    status = result.status.value
    given_up = sum(text.startswith("pipe blocked") for _, text in result.events)
    recovered = sum(text.startswith("stall: past it") for _, text in result.events)
    if deposits:
        from pipemap.recorder.session import covers

        # Blocked pipes cannot be driven: what is reachable without them counts.
        covered = covers(network, deposits, visited, path)
    if result.status is RunStatus.FINISHED and not covered:
        status = "stopped early: not every node and pipe was visited"
    out.write(
        f"network {args.network}, condition autonomous, explore {explore.value}: "
        f"{len(result.sweeps)} sweeps at {len(visited)}/{len(network.nodes)} nodes "
        f"({driven}/{len(pipes)} pipes), "
        f"{result.distance_m:.2f} m in {result.duration_ns / 1e9:.0f} s simulated, {status}"
        + (
            f"; {_conditions(deposits, faults)}: got past {recovered} stall(s), gave up "
            f"{given_up} pipe(s) as blocked"
            if deposits or faults
            else ""
        )
        + "\n"
    )
    return 0 if result.status is RunStatus.FINISHED and covered else 1


def _localize_with_probes(localizer, visit, folder: Path, fov_rad: float) -> int:  # type: ignore[no-untyped-def]
    """Run the online localizer on a visit; each probe it asks for is swept and saved."""
    saved = 0

    class _Probes:
        def probe(self, request):  # type: ignore[no-untyped-def]
            nonlocal saved
            sweep, truth = visit.probe(request.yaw_rad, request.forward_m, request.left_m)
            write_image_set(
                folder / "probes" / request.kind.value,
                sweep.images,
                _info(truth.camera_pose, visit.node),
                sweep.camera_angle_rad,
            )
            saved += 1
            return _gray_set(sweep.images, fov_rad, sweep.camera_angle_rad)

    first = visit.sweep
    localizer.localize(_gray_set(first.images, fov_rad, first.camera_angle_rad), _Probes())
    return saved
