"""A robot off level: the IMU's levelling, or without an IMU reading the two-view fit's
tilt refinement, keeps revisit rotations right.

Renders the paper's tour at 400 px with the robot tilted up to 3 degrees at each
junction (about 15 s), and localizes it with and without each
(``benchmarks/bench_tilt.py`` and ``bench_tilt_log.py`` measure more runs).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from pipemap.localizer import ImageSet, Localizer, LocalizerConfig, TwoViewConfig
from pipemap.sim import CameraSpec, Condition, Episode, SimConfig, World, build_network
from pipemap.sim.network import wrap_rad

_GRAY = np.array([0.299, 0.587, 0.114], dtype=np.float32)


@pytest.fixture(scope="module")
def tilted_tour() -> list:  # type: ignore[type-arg]
    config = SimConfig(
        Condition.PERFECT, seed=0, camera=CameraSpec(resolution_px=400), tilt_rad=math.radians(3)
    )
    with World(build_network("paper"), seed=0) as world:
        return [
            (
                ImageSet(
                    np.stack([im.astype(np.float32) @ _GRAY for im in v.sweep.images]),
                    camera_angle_rad=v.sweep.camera_angle_rad,
                    imu_tilt_rad=v.sweep.imu_tilt_rad,
                ),
                v.node,
                v.pose.yaw_rad,
            )
            for v in Episode(world, config).visits()
        ]


def _without_imu(tour: list) -> list:  # type: ignore[type-arg]
    """The tour as sweeps without an IMU reading (as the paper's image sets are)."""
    return [(replace(images, imu_tilt_rad=None), node, yaw) for images, node, yaw in tour]


def _revisit_errors(tour: list, refine: bool, imu_level: bool = True) -> list[float]:  # type: ignore[type-arg]
    two_view = replace(TwoViewConfig(), tilt=refine, imu_level=imu_level)
    localizer = Localizer(LocalizerConfig(active_vision=False, lamp=True, two_view_config=two_view))
    first: dict[str, tuple[int, float]] = {}
    errors = []
    for images, node, heading in tour:
        d = localizer.localize(images)
        if node in first:
            assert d.known and d.node == first[node][0], node
            assert d.rotation_rad is not None
            errors.append(abs(wrap_rad(d.rotation_rad - wrap_rad(first[node][1] - heading))))
        else:
            assert not d.known, node
            first[node] = (d.node, heading)
    return errors


def test_the_tilt_refinement_earns_its_keep(tilted_tour: list) -> None:  # type: ignore[type-arg]
    tour = _without_imu(tilted_tour)
    with_tilt = _revisit_errors(tour, refine=True)
    level_only = _revisit_errors(tour, refine=False)
    assert len(with_tilt) == 6
    assert max(with_tilt) <= 0.01
    assert max(level_only) > 0.02  # measured 0.038: the refinement is what keeps it right


def test_the_imu_levelling_earns_its_keep(tilted_tour: list) -> None:  # type: ignore[type-arg]
    assert all(images.imu_tilt_rad is not None for images, _, _ in tilted_tour)
    assert any(images.imu_tilt_rad != (0.0, 0.0) for images, _, _ in tilted_tour)
    levelled = _revisit_errors(tilted_tour, refine=False)
    ignored = _revisit_errors(tilted_tour, refine=False, imu_level=False)
    assert len(levelled) == 6
    # Levelled by the IMU (its reading 0.002 rad off), no refinement is needed.
    assert max(levelled) <= 0.01
    assert max(ignored) > 0.02  # the same as a sweep without a reading
