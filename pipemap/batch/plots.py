"""Box plots drawn with OpenCV, for the experiment's and the batch report's figures
(no plotting library is a dependency). Deterministic: the same values give the same
PNG bytes."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["Box", "box_plot"]

_FONT = cv2.FONT_HERSHEY_SIMPLEX
_INK = (40, 40, 40)
_GRID = (225, 225, 225)
#: Colours (BGR) for the two kinds of pair.
SAME = (60, 140, 40)
DIFFERENT = (40, 90, 200)


@dataclass(frozen=True)
class Box:
    """One box: its values, the colour (BGR) and a label under the axis."""

    values: Sequence[float]
    colour: tuple[int, int, int]
    label: str = ""


def _text(
    image: np.ndarray, text: str, x: int, y: int, scale: float = 0.45, centre: bool = False
) -> None:
    if centre:
        (w, _), _ = cv2.getTextSize(text, _FONT, scale, 1)
        x -= w // 2
    cv2.putText(image, text, (x, y), _FONT, scale, _INK, 1, cv2.LINE_AA)


def box_plot(
    groups: Sequence[tuple[str, Sequence[Box]]],
    title: str,
    threshold: float | None = None,
    y_label: str = "similarity",
    y_range: tuple[float, float] = (0.0, 1.0),
    legend: Sequence[tuple[str, tuple[int, int, int]]] = (),
) -> np.ndarray:
    """A BGR image of box plots, one cluster per group: box from the first to the
    third quartile, a line at the median, whiskers to the furthest value within 1.5
    interquartile ranges, every value drawn as a dot, and a dashed threshold line."""
    boxes = sum(len(b) for _, b in groups)
    width = max(480, 90 + 56 * (boxes + len(groups)))
    height = 420
    left, right, top, bottom = 70, width - 20, 50, height - 70
    image = np.full((height, width, 3), 255, np.uint8)
    lo, hi = y_range

    def y_of(v: float) -> int:
        return int(round(bottom - (min(max(v, lo), hi) - lo) / (hi - lo) * (bottom - top)))

    digits = 1 if hi - lo >= 1.0 else 2 if hi - lo >= 0.1 else 3
    for k in range(11):
        v = lo + (hi - lo) * k / 10
        cv2.line(image, (left, y_of(v)), (right, y_of(v)), _GRID, 1)
        _text(image, f"{v:.{digits}f}", left - 40, y_of(v) + 4, 0.4)
    cv2.line(image, (left, top), (left, bottom), _INK, 1)
    cv2.line(image, (left, bottom), (right, bottom), _INK, 1)
    _text(image, title, width // 2, 28, 0.55, centre=True)
    _text(image, y_label, 6, top - 12, 0.4)
    slot = (right - left) / max(1, boxes + len(groups))
    x = left + slot
    for name, cluster in groups:
        first = x
        for box in cluster:
            _draw_box(image, box, int(round(x)), int(slot * 0.32), y_of)
            if box.label:
                _text(image, box.label, int(round(x)), bottom + 16, 0.35, centre=True)
            x += slot
        _text(image, name, int(round((first + x - slot) / 2)), bottom + 36, 0.45, centre=True)
        x += slot
    if threshold is not None:
        y = y_of(threshold)
        for x0 in range(left, right, 12):
            cv2.line(image, (x0, y), (min(x0 + 6, right), y), (0, 0, 220), 1)
        _text(image, f"threshold {threshold:g}", right - 120, y - 6, 0.4)
    lx = left + 8
    for text, colour in legend:
        cv2.rectangle(image, (lx, height - 22), (lx + 12, height - 10), colour, -1)
        _text(image, text, lx + 18, height - 11, 0.4)
        lx += 30 + 8 * len(text)
    return image


def _draw_box(image: np.ndarray, box: Box, x: int, half: int, y_of: Callable[[float], int]) -> None:
    values = np.sort(np.asarray(box.values, dtype=float))
    if values.size == 0:
        _text(image, "none", x, y_of(0.05), 0.35, centre=True)
        return
    q1, median, q3 = np.percentile(values, [25, 50, 75])
    reach = 1.5 * (q3 - q1)
    inside = values[(values >= q1 - reach) & (values <= q3 + reach)]
    low, high = float(inside.min()), float(inside.max())
    cv2.line(image, (x, y_of(low)), (x, y_of(q1)), box.colour, 1)
    cv2.line(image, (x, y_of(q3)), (x, y_of(high)), box.colour, 1)
    for v in (low, high):
        cv2.line(image, (x - half // 2, y_of(v)), (x + half // 2, y_of(v)), box.colour, 1)
    cv2.rectangle(image, (x - half, y_of(q3)), (x + half, y_of(q1)), box.colour, 2)
    cv2.line(image, (x - half, y_of(median)), (x + half, y_of(median)), box.colour, 2)
    for i, v in enumerate(values):
        jitter = ((i * 7) % 11 - 5) * half // 8  # a fixed spread, not random
        cv2.circle(image, (x + jitter, y_of(float(v))), 2, box.colour, -1, cv2.LINE_AA)
