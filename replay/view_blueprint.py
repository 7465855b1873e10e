"""The layout a view opens with: the 3D scene, the camera, the map, the signals, the log.

rerun lays out a recording by itself from its entities, but for a pipemap log that
gives a dozen small plots and no obvious place to look. This blueprint puts the
3D scene (network, robot, range rays, camera direction, trajectory) top left and
the camera image and the growing topological map under it; on the right, the
ranges, the IMU, the wheels and the commands as time series, and the text log of
decisions, controller states and events. The time panel opens on ``sim_time``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pipemap.replay.view_topics import TIMELINE

if TYPE_CHECKING:
    import rerun.blueprint as rrb

__all__ = ["view_blueprint"]


def view_blueprint() -> rrb.Blueprint:
    """The default layout of a pipemap view."""
    import rerun.blueprint as rrb

    scene = rrb.Spatial3DView(name="pipe network (truth) and robot", origin="world")
    camera = rrb.Spatial2DView(name="camera", origin="camera")
    topomap = rrb.GraphView(name="topological map (replay)", origin="map")
    signals = [
        rrb.TimeSeriesView(name="range (m): front, left, right", origin="sensors/tof"),
        rrb.TimeSeriesView(name="IMU", origin="sensors/imu"),
        rrb.TimeSeriesView(name="wheel encoders (ticks)", origin="sensors/wheels"),
        rrb.TimeSeriesView(name="commands", origin="controller"),
    ]
    text = rrb.TextLogView(name="decisions, controller, events", origin="log")
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(
                scene,
                rrb.Horizontal(camera, topomap),
                row_shares=[3, 2],
            ),
            rrb.Vertical(*signals, text, row_shares=[1, 1, 1, 1, 2]),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=TIMELINE, state="expanded"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.BlueprintPanel(state="collapsed"),
    )
