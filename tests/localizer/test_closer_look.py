"""The closer look (``localizer/closer.py``) on the revisit that made it needed.

``data/random17_seed7_visits_6_18.npz``: two sweeps of one junction from the 400 px
run of ``random:17`` seed 7 with probe moves (visit 18 asked for none), as its log
holds them (lamp-lit 8-bit frames, exits, departures). Visit 6 saw the junction first; visit 18
came back to it out of a dead end and stopped 10.4 cm from visit 6's spot. Written
by ``python benchmarks/why_two_view.py LOG 18 --save PATH`` on that run's log.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pipemap.errors import LocalizerError
from pipemap.localizer import ImageSet, Localizer, LocalizerConfig, normalised
from pipemap.localizer.closer import CloserLook, closer_config
from pipemap.localizer.twoview import TwoViewConfig, fit_two_view, sweep_features

DATA = Path(__file__).parent / "data" / "random17_seed7_visits_6_18.npz"
#: The rotation between the two sweeps the ports allow (the junction's pipes line up).
ROTATION_RAD = 2.768


def _sweep(data: np.lib.npyio.NpzFile, visit: int) -> ImageSet:
    fov, angle = data[f"camera_{visit}"]
    return ImageSet(data[f"frames_{visit}"], fov_rad=float(fov), camera_angle_rad=float(angle))


@pytest.fixture(scope="module")
def data() -> np.lib.npyio.NpzFile:
    return np.load(DATA)


def _walk(loc: Localizer, data: np.lib.npyio.NpzFile) -> tuple[int, object]:
    """Visit 6's junction, the pipe to a dead end (a sweep of noise) and back: the map
    expects visit 6's junction when visit 18 comes."""
    first = loc.localize(_sweep(data, 6), exits_rad=tuple(data["exits_6"]))
    assert first.node == 0
    # Exit 0 (0.42 rad) is the pipe the robot took to the dead end: visit 18's exit
    # behind it (-3.14 rad) lines up with it, turned by the rotation.
    loc.depart(float(data["exits_6"][0]))
    shape = data["frames_6"].shape
    noise = np.random.default_rng(7).integers(0, 256, shape, dtype=np.uint8)
    fov = float(data["camera_6"][0])
    dead_end = loc.localize(ImageSet(noise, fov_rad=fov), exits_rad=(math.pi,))
    assert not dead_end.known
    loc.depart(math.pi)
    assert loc.expected_node() == 0
    return 0, loc.localize(_sweep(data, 18), exits_rad=tuple(data["exits_18"]))


@pytest.mark.parametrize("closer_look", [True, False])
def test_the_revisit_10_cm_off_is_recognised_by_the_closer_look(
    data: np.lib.npyio.NpzFile, closer_look: bool
) -> None:
    keypoints = LocalizerConfig().closer_keypoints_per_image if closer_look else 0
    loc = Localizer(LocalizerConfig(lamp=True, closer_keypoints_per_image=keypoints))
    node, decision = _walk(loc, data)
    assert decision.known is closer_look  # type: ignore[attr-defined]
    if closer_look:
        assert decision.node == node  # type: ignore[attr-defined]
        fit = decision.two_view  # type: ignore[attr-defined]
        assert fit is not None and fit.inliers >= loc.config.expected_inliers
        assert abs(math.remainder(fit.rotation_rad - ROTATION_RAD, 2 * math.pi)) < 0.05
    assert loc._closer.taken == (1 if closer_look else 0)


def test_the_reduced_keypoints_fall_short_where_full_detail_fits(
    data: np.lib.npyio.NpzFile,
) -> None:
    """The cause: on the reduced images the pair fits with 23 inliers, one short of
    the expected junction's 24; on the closer look's keypoints with 44."""
    illumination = LocalizerConfig().illumination
    query, known = (normalised(_sweep(data, v), illumination) for v in (18, 6))
    base = replace(TwoViewConfig(), min_inliers=LocalizerConfig().expected_inliers)
    assert (
        fit_two_view(sweep_features(query, base), sweep_features(known, base), base, 2.768) is None
    )
    loose = replace(base, min_inliers=12)
    reduced = fit_two_view(sweep_features(query, loose), sweep_features(known, loose), loose, 2.768)
    assert reduced is not None and reduced.inliers < base.min_inliers
    closer = closer_config(base, LocalizerConfig().closer_keypoints_per_image)
    fit = fit_two_view(sweep_features(query, closer), sweep_features(known, closer), closer, 2.768)
    assert fit is not None and fit.inliers >= 1.5 * base.min_inliers


def test_only_the_expected_junction_gets_a_closer_look(data: np.lib.npyio.NpzFile) -> None:
    """Without the map's expectation visit 6's junction needs ``verify_inliers`` (48)
    and gets no closer look: the visit is new."""

    class NoPrior(Localizer):
        def expected_node(self) -> int | None:
            return None

    loc = NoPrior(LocalizerConfig(lamp=True))
    loc.localize(_sweep(data, 6), exits_rad=tuple(data["exits_6"]))
    decision = loc.localize(_sweep(data, 18), exits_rad=tuple(data["exits_18"]))
    assert not decision.known and loc._closer.taken == 0


def test_a_sweep_the_check_sees_whole_gets_no_closer_look(data: np.lib.npyio.NpzFile) -> None:
    """At 200 px the check already sees the images at their own size: nothing is kept."""
    frames = data["frames_6"][:, ::2, ::2]
    small = ImageSet(np.ascontiguousarray(frames), fov_rad=float(data["camera_6"][0]))
    look = CloserLook(LocalizerConfig())
    assert look.sharper(_sweep(data, 6)) and not look.sharper(small)
    look.keep(0, small)
    assert look.known(0) is None and look.pair(0, small) is None and look.nbytes == 0
    look.keep(1, _sweep(data, 6))
    assert look.known(1) is not None and look.nbytes > 0


def test_closer_keypoints_are_validated() -> None:
    with pytest.raises(LocalizerError, match="closer_keypoints_per_image"):
        LocalizerConfig(closer_keypoints_per_image=-1)


@pytest.mark.parametrize("keeps_images", [True, False])
def test_keypoints_are_found_only_for_the_junction_looked_at_closer(
    data: np.lib.npyio.NpzFile, keeps_images: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Keeping the images (the default), no new junction's closer-look keypoints are
    found until a closer look asks for them, and then only the visit's and the
    expected junction's; without, every new junction's at once. The decision is the
    same both ways."""
    from pipemap.localizer import closer

    found: list[int] = []
    real = closer.detected
    monkeypatch.setattr(closer, "detected", lambda *a: found.append(a[0].count) or real(*a))
    loc = Localizer(LocalizerConfig(lamp=True, closer_keeps_images=keeps_images))
    loc.localize(_sweep(data, 6), exits_rad=tuple(data["exits_6"]))
    images = 6 * _sweep(data, 6).kept_rows * 400  # one byte a pixel ORB would see
    first = loc._closer.nbytes
    assert len(found) == loc._closer.detections == (0 if keeps_images else 1)
    assert (first >= images) is keeps_images

    loc = Localizer(LocalizerConfig(lamp=True, closer_keeps_images=keeps_images))
    node, decision = _walk(loc, data)  # two new junctions, then the closer look
    assert decision.known and decision.node == node  # type: ignore[attr-defined]
    assert loc._closer.taken == 1
    # Lazily: the revisit's and visit 6's, not the dead end's (still its images).
    assert loc._closer.detections == (2 if keeps_images else 3)
    assert len(found) == (2 if keeps_images else 4)
    if keeps_images:  # visit 6's images gave way to its keypoints
        assert images < loc._closer.nbytes < images + first // 2


def test_the_closer_look_finds_the_same_keypoints_lazily(data: np.lib.npyio.NpzFile) -> None:
    """A junction's keypoints found from its kept images are the very ones found at once."""
    eager = CloserLook(LocalizerConfig(closer_keeps_images=False))
    lazy = CloserLook(LocalizerConfig())
    sweep = _sweep(data, 6)
    eager.keep(0, sweep)
    lazy.keep(0, sweep)
    assert lazy.detections == 0 and eager.detections == 1
    a, b = eager.known(0), lazy.known(0)
    assert a is not None and b is not None and lazy.detections == 1
    assert np.array_equal(a.bearings, b.bearings) and np.array_equal(a.descriptors, b.descriptors)
    assert lazy.nbytes == eager.nbytes
    lazy.known(0)
    assert lazy.detections == 1  # found once
