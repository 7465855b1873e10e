"""Synthetic junctions for the localizer's tests: smooth random panoramas (blurred
noise, one seed per junction), each image set N=6 views cut at equal steps, each view
wider than the step so that neighbours overlap, like the paper's camera sweep; and a
probe source answering from a table."""

from __future__ import annotations

import functools
import math
from dataclasses import replace

import cv2
import numpy as np

from pipemap.localizer.imageset import ImageSet
from pipemap.localizer.localizer import (
    PAPER,
    Localizer,
    ProbeKind,
    ProbeRequest,
)

ROWS = 128


COLS = 960


N = 6


STEP_PX = COLS // N  # 160


WIDTH = 192


#: The view's field of view matches the panorama's geometry: 192 of 960 columns.
FOV_RAD = 2.0 * math.pi * WIDTH / COLS


STEP_RAD = 2.0 * math.pi / N


#: High enough that only a (near) exact revisit is known: a set with added noise is
#: weak (about 0.96: the paper's quarter scale averages the noise of 16 pixels) and
#: other junctions are far below (under 0.45).
STRICT = 0.985


PAPER_ORDER = [ProbeKind.ROTATE, ProbeKind.FORWARD, ProbeKind.BACK, ProbeKind.LEFT, ProbeKind.RIGHT]


@functools.cache
def panorama(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    noise = rng.normal(size=(ROWS, COLS)).astype(np.float32)
    smooth = cv2.GaussianBlur(noise, (0, 0), 3.0)
    out = 128.0 + 40.0 * smooth / float(smooth.std())
    out.setflags(write=False)
    return out


def views(seed: int, start_px: int = 0) -> np.ndarray:
    pano = panorama(seed)
    starts = [start_px + j * STEP_PX for j in range(N)]
    return np.stack([pano[:, np.arange(s, s + WIDTH) % COLS] for s in starts])


def junction(seed: int, *, roll: int = 0, noise: float = 0.0, noise_seed: int = 99) -> ImageSet:
    """The image set of junction ``seed``; ``roll`` starts the sweep ``roll`` images
    later (a cyclic permutation), ``noise`` adds Gaussian noise of that many
    standard deviations of the images."""
    images = views(seed)
    if noise:
        rng = np.random.default_rng(noise_seed)
        images = images + noise * float(images.std()) * rng.normal(size=images.shape)
    return ImageSet(np.roll(images, roll, axis=0), fov_rad=FOV_RAD)


class FakeProbes:
    """A :class:`ProbeSource` that records requests and answers from a table."""

    def __init__(
        self,
        answers: dict[ProbeKind, ImageSet | None] | None = None,
        default: ImageSet | None = None,
    ) -> None:
        self.answers = answers if answers is not None else {}
        self.default = default
        self.requests: list[ProbeRequest] = []

    def probe(self, request: ProbeRequest) -> ImageSet | None:
        self.requests.append(request)
        return self.answers.get(request.kind, self.default)

    @property
    def kinds(self) -> list[ProbeKind]:
        return [r.kind for r in self.requests]


def strict_with(*seeds: int, **config: object) -> Localizer:
    # These tests exercise the paper's rules, under which every known junction competes
    # and the threshold decides.
    loc = Localizer(replace(PAPER, threshold=STRICT, **config))  # type: ignore[arg-type]
    for seed in seeds:
        assert not loc.localize(junction(seed)).known
    return loc


PI = math.pi
#: A T seen from its stem (behind), and a corner.
TEE_EXITS = (PI, PI / 2, -PI / 2)
CORNER_EXITS = (PI, PI / 2)
