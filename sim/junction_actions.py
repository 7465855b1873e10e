"""What the explorer does at a node: sweep the camera, scan for exits, re-centre.

Arrived at a node, the robot re-centres (:func:`recentre`: a scan, then the widest
circle among the walls it saw or, at a shallow corner, the crossing of the pipes'
axes; against a wall ahead it settles by the front range,
:func:`settle_on_wall_ahead`), sweeps the camera (:func:`sweep`) and scans once
more for the exits (:func:`scan`). The geometry is in :mod:`sim.scan_geometry`;
these act on a :class:`~pipemap.sim.motion.Motion`.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from pipemap.sim.episode import Pose, Sweep, SweepTruth, sweep_start_angle
from pipemap.sim.motion import Motion
from pipemap.sim.policy import RunStatus
from pipemap.sim.robot import PlanarPose, RangeReading
from pipemap.sim.scan_geometry import (
    HALF_WIDTH_M,
    axes_crossing,
    opening_headings,
    through_wall,
    wall_points,
    widest_centre,
)
from pipemap.sim.stream import NodeArrival, SweepEnd, SweepImage, SweepStart
from pipemap.sim.world import CameraSpec

__all__ = ["recentre", "scan", "scan_samples", "settle_on_wall_ahead", "sweep", "take_sweep"]


def sweep(
    m: Motion,
    camera: CameraSpec,
    true_node_of: Callable[[PlanarPose], str] | None,
    tilt_rad: tuple[float, float] = (0.0, 0.0),
    imu_tilt_rad: tuple[float, float] = (0.0, 0.0),
) -> None:
    """Sweep the camera: ``images_per_sweep`` images, clockwise, from the multiple of
    ``2*pi/N`` nearest the heading estimate; the robot stands still meanwhile. The
    sweep is labelled by ``true_node_of`` (ground truth, for scoring only). A robot
    off level stands at ``tilt_rad`` (roll, pitch) and its IMU reads ``imu_tilt_rad``."""
    number = len(m.result.sweeps) + 1  # the visit's number
    if m.sink is not None:
        m.sink(NodeArrival(m.robot.t_ns, number))
    take_sweep(m, camera, true_node_of, number, None, tilt_rad, imu_tilt_rad)


def take_sweep(
    m: Motion,
    camera: CameraSpec,
    true_node_of: Callable[[PlanarPose], str] | None,
    visit_id: int,
    probe: tuple[str, float, float, float] | None,
    tilt_rad: tuple[float, float] = (0.0, 0.0),
    imu_tilt_rad: tuple[float, float] = (0.0, 0.0),
) -> Sweep:
    """One sweep of visit ``visit_id`` where the robot stands (see :func:`sweep`):
    the visit's own (``probe`` ``None``: kept in the run's result) or an active-vision
    probe sweep, ``probe`` its ``(kind, yaw, forward, left)`` move. Sweeps are numbered
    in the order taken: without probes, as the visits."""
    c = m.config
    m.state = "sweeping"
    pose = m.robot.pose
    n = c.images_per_sweep
    number = len(m.result.sweeps) + m.probe_sweeps + 1
    angle = sweep_start_angle(m.yaw_est, n, c.align_sweeps)
    first = pose.yaw_rad + angle  # where the camera truly points: the robot's true yaw
    sink = m.sink
    if sink is not None:
        fov = camera.fov_rad
        sink(SweepStart(m.robot.t_ns, number, visit_id, n, angle, fov, probe, imu_tilt_rad))
    roll, pitch = tilt_rad
    images = []
    for j in range(n):
        step = j * 2.0 * math.pi / n
        eye = (pose.x_m + 1.3e-4, pose.y_m + 0.7e-4, c.camera_height_m)
        if roll == 0.0 and pitch == 0.0:
            images.append(m.robot.world.render(eye, first - step, camera))
        else:
            world = m.robot.world
            images.append(world.render_tilted(eye, pose.yaw_rad, angle - step, roll, pitch, camera))
        if sink is not None:
            sink(SweepImage(m.robot.t_ns, number, visit_id, j, angle - step, images[-1]))
        m.drive(0.0, 0.0, c.sweep_step_ns)  # the camera motor turns; the robot waits
    truth = true_node_of(pose) if true_node_of is not None else ""
    start = Pose(pose.x_m, pose.y_m, c.camera_height_m, roll, pitch, first)
    moved = None if probe is None else probe[1:]
    taken = Sweep(np.stack(images), moved, camera_angle_rad=angle, imu_tilt_rad=imu_tilt_rad)
    known = SweepTruth(str(truth), start)
    if probe is None:
        m.result.sweeps.append(taken)
        m.result.sweep_truths.append(known)
        m.event(f"sweep {number}")
    else:
        m.probe_sweeps += 1
        m.event(f"probe sweep {number} ({probe[0]}) of visit {visit_id}")
    if sink is not None:
        sink(SweepEnd(m.robot.t_ns, number, visit_id, taken, known))
    return taken


def scan_samples(m: Motion) -> list[tuple[float, float]]:
    """Turn once round in place: (estimated heading, front range) pairs."""
    c = m.config
    m.state = "scanning"
    samples: list[tuple[float, float]] = []
    start = m.yaw_est
    while m.yaw_est - start < 2.0 * math.pi:
        m.drive(0.0, c.turn_rate_rps, c.control_period_ns)
        samples.append((m.yaw_est, m.ranges[0]))
        if m.stalled():  # cannot turn: the watchdog ends the run later
            break
    m.turn_to(start)
    return samples


def scan(m: Motion) -> tuple[list[float], list[float]]:
    """Turn once round in place; the headings (estimated) of the exits, twice, in
    the same order: as reported (each opening's deepest samples, the pipe's axis;
    see :func:`~pipemap.sim.scan_geometry.opening_headings`) and as steered by
    (each opening's middle, which keeps the robot clear of the mouth's walls)."""
    samples = scan_samples(m)
    c = m.config
    return (
        opening_headings(samples, c.scan_open_m, c.exit_depth_fraction),
        opening_headings(samples, c.scan_open_m),
    )


def recentre(m: Motion, expected: np.ndarray) -> RunStatus | None:
    """Move to the node centre found from a range scan, then face as before.

    The centre is where the largest circle fits among the wall points seen
    (a 2 mm grid within 8 cm): the junction's walls all keep the pipe radius
    from it, and openings hold no points to pull it off. Along a pipe's axis
    every point fits as wide a circle; among those ties the one nearest to
    where the approach expected the centre wins.
    """
    c = m.config
    m.state = "recentring"
    facing = m.yaw_est
    forward = m.robot.spec.tof_forward_m
    samples = scan_samples(m)
    for _ in range(c.touch_retries):
        # The nose swung through a wall: the scan saw out of the junction there. Back
        # off from that wall and scan again, so no wall is missing from the circle fit.
        walls = through_wall(samples, m.robot.spec.tof_max_range_m, c.touch_m)
        if not walls:
            break
        away = math.atan2(-sum(math.sin(w) for w in walls), -sum(math.cos(w) for w in walls))
        m.event("the range scan reached through a wall: backing off to scan again")
        m.turn_to(away)
        status = m.straight(c.touch_backoff_m, away)
        if status is not None:
            return status
        samples = scan_samples(m)
    points = wall_points(samples, m.xy_est, forward, c.scan_open_m)
    if len(points) < 8:
        return None
    target = widest_centre(points, m.xy_est, expected)
    openings = opening_headings(samples, c.scan_open_m)
    if len(openings) == 2:
        corner = axes_crossing(
            samples, forward, points, m.xy_est, target, openings, c.shallow_corner_deg
        )
        if corner is not None:
            target = corner
    move = target - m.xy_est
    distance = float(np.linalg.norm(move))
    if distance > 0.01:
        heading = math.atan2(move[1], move[0])
        m.turn_to(heading)
        status = m.straight(distance, heading)
        if status is not None:
            return status
    m.turn_to(facing)
    # Settle only where the wall ahead is square to the heading: no opening within
    # 80 degrees of it (a dead end, a right-angle corner or T), not at a Y or a
    # sharp corner, whose walls ahead stand at other distances.
    clear = math.radians(c.settle_clear_deg)
    if all(abs(math.remainder(o - facing, 2.0 * math.pi)) > clear for o in openings):
        return settle_on_wall_ahead(m)
    return None


def settle_on_wall_ahead(m: Motion) -> RunStatus | None:
    """With a wall straight ahead, stand where the front range puts the node centre.

    The scan cannot tell where along the arrival pipe the centre lies when that
    pipe ends in a wall: a dead end's cap, a right-angle corner's outer wall, the
    far wall of a T entered by its stem. That wall is the pipe's radius from the centre, so
    the front ranger then reads a known distance; standing there makes two visits
    of such a node sweep from the same place.
    """
    c = m.config
    spec = m.robot.spec
    m.state = "settling"
    start = len(m.result.readings)
    m.drive(0.0, 0.0, c.settle_ns)
    fronts = [r.ranges_m[0] for r in m.result.readings[start:] if isinstance(r, RangeReading)]
    if not fronts:
        return None
    front = float(np.median(fronts))
    if front > c.scan_open_m:  # open ahead: the scan's centre stands
        return None
    error = front - (HALF_WIDTH_M - spec.tof_forward_m)
    if abs(error) < c.settle_tolerance_m:
        return None
    return m.straight(error, m.yaw_est)
