"""Geometry in the plane of the network: headings, segments, distances.

Pure functions on ``(x, y)`` tuples in metres, shared by the network's validation
(:mod:`sim.network_model`) and the random layouts (:mod:`sim.random_layout`).
"""

from __future__ import annotations

import math

__all__ = ["EPS", "heading_rad", "point_segment_distance_m", "segments_touch", "wrap_rad"]

#: Tolerance of the geometric tests, in metres (or square metres for orientations).
EPS = 1e-9


def wrap_rad(angle_rad: float) -> float:
    """``angle_rad`` wrapped into (-pi, pi]."""
    wrapped = math.remainder(angle_rad, 2.0 * math.pi)
    return wrapped + 2.0 * math.pi if wrapped <= -math.pi else wrapped


def heading_rad(x0: float, y0: float, x1: float, y1: float) -> float:
    """Heading of the line from ``(x0, y0)`` to ``(x1, y1)``, in (-pi, pi]."""
    return wrap_rad(math.atan2(y1 - y0, x1 - x0))


def _orient(p: tuple[float, float], q: tuple[float, float], r: tuple[float, float]) -> float:
    return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])


def _on_segment(p: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> bool:
    return (
        min(a[0], b[0]) - EPS <= p[0] <= max(a[0], b[0]) + EPS
        and min(a[1], b[1]) - EPS <= p[1] <= max(a[1], b[1]) + EPS
    )


def segments_touch(
    p1: tuple[float, float],
    p2: tuple[float, float],
    q1: tuple[float, float],
    q2: tuple[float, float],
) -> bool:
    """Whether the closed segments p1-p2 and q1-q2 share a point (collinear overlap too)."""
    o1, o2 = _orient(p1, p2, q1), _orient(p1, p2, q2)
    o3, o4 = _orient(q1, q2, p1), _orient(q1, q2, p2)
    if o1 * o2 < 0 and o3 * o4 < 0:
        return True
    return (
        (abs(o1) <= EPS and _on_segment(q1, p1, p2))
        or (abs(o2) <= EPS and _on_segment(q2, p1, p2))
        or (abs(o3) <= EPS and _on_segment(p1, q1, q2))
        or (abs(o4) <= EPS and _on_segment(p2, q1, q2))
    )


def point_segment_distance_m(
    p: tuple[float, float], a: tuple[float, float], b: tuple[float, float]
) -> float:
    """Distance from point ``p`` to the closed segment a-b."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    length_sq = dx * dx + dy * dy
    t = 0.0 if length_sq == 0.0 else ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length_sq
    t = min(1.0, max(0.0, t))
    return math.hypot(p[0] - (a[0] + t * dx), p[1] - (a[1] + t * dy))
