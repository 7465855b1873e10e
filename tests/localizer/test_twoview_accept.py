"""A pair whose first quarter of keypoints already fits clearly is fitted on that
quarter alone (:attr:`TwoViewConfig.accept_share`); a fit compared with it matches
as many stages (:attr:`TwoViewConfig.stage_limit`); and should the quarter's fit
fail, every stage is matched, as without the early stop."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from pipemap.localizer import stages, twoview
from pipemap.localizer.twoview import TwoViewConfig, fit_two_view, sweep_features
from tests.conftest import PaperSet

#: Same junction from other entries: the first quarter's count on the coarse grid.
PAIRS = [("1", "1_noise"), ("2_noise", "2_active"), ("3_noise", "3")]


@pytest.fixture(scope="module")
def tilted(paper_sets: dict[str, PaperSet]) -> dict[str, twoview.SweepFeatures]:
    """The paper's sets as they are: the robot up to 0.05 rad off level, no IMU."""
    names = {n for pair in PAIRS for n in pair}
    return {n: sweep_features(paper_sets[n].images) for n in sorted(names)}


@pytest.fixture(scope="module")
def features(tilted: dict[str, twoview.SweepFeatures]) -> dict[str, twoview.SweepFeatures]:
    """The same keypoints as if an IMU had levelled them (so the planar fit is the
    fit, as in pipemap's simulated runs, and no tilted refinement follows)."""
    return {n: replace(f, levelled=True) for n, f in tilted.items()}


def _quarter(known: twoview.SweepFeatures) -> int:
    """Keypoints of the first stage: the first two eighths."""
    return len(range(0, len(known), 8)) + len(range(4, len(known), 8))


def _quarter_count(
    monkeypatch: pytest.MonkeyPatch, query: Any, known: Any, config: TwoViewConfig
) -> int:
    """The first quarter's best count on the coarse grid (its gate's, the only grid
    a gate counts at 24 inliers asked: no early gate below 3, and the quarter's
    count passes every later gate)."""
    counts: list[int] = []
    real = stages._coarse

    def counting(*args: Any) -> tuple[np.ndarray, np.ndarray, list[float]]:
        got = real(*args)
        counts.append(int(got[0].max(initial=0)))
        return got

    monkeypatch.setattr(stages, "_coarse", counting)
    fit_two_view(query, known, replace(config, accept_share=0.0))
    monkeypatch.setattr(stages, "_coarse", real)
    assert len(counts) == 1
    return counts[0]


@pytest.mark.parametrize(("q", "k"), PAIRS)
def test_a_clear_first_quarter_is_fitted_alone(
    features: dict[str, twoview.SweepFeatures], seen: list[int], q: str, k: str
) -> None:
    """The map's own junction (24 inliers asked), sweeps levelled: every pair's
    first quarter counts twice that or more, so only that quarter is matched, and
    its fit has the rotation of the fit of every keypoint to a few thousandths of a
    radian."""
    config = TwoViewConfig(min_inliers=24, accept_share=2.0)
    quarter = fit_two_view(features[q], features[k], config)
    assert sum(seen) == _quarter(features[k])
    seen.clear()
    whole = fit_two_view(features[q], features[k], replace(config, accept_share=0.0))
    assert sum(seen) == len(features[k])
    assert quarter is not None and whole is not None
    assert quarter.stages == 1 and whole.stages is None
    assert 24 <= quarter.inliers < whole.inliers and quarter.matches < whole.matches
    assert abs(quarter.rotation_rad - whole.rotation_rad) < 0.005


@pytest.mark.parametrize(("q", "k"), PAIRS)
def test_the_share_is_a_bound_the_quarter_must_reach(
    monkeypatch: pytest.MonkeyPatch,
    features: dict[str, twoview.SweepFeatures],
    seen: list[int],
    q: str,
    k: str,
) -> None:
    """At a share the quarter's count just reaches, the fit stops after it; one
    more keypoint asked, and every stage is matched: the fit of every keypoint."""
    config = TwoViewConfig(min_inliers=24)
    count = _quarter_count(monkeypatch, features[q], features[k], config)
    reached = fit_two_view(features[q], features[k], replace(config, accept_share=count / 24))
    assert reached is not None and reached.stages == 1
    seen.clear()
    short = fit_two_view(features[q], features[k], replace(config, accept_share=(count + 1) / 24))
    assert sum(seen) == len(features[k])
    assert short == fit_two_view(features[q], features[k], replace(config, accept_share=0.0))
    assert short is not None and short.stages is None


def test_a_quarter_whose_fit_fails_is_fitted_again_on_every_stage(
    monkeypatch: pytest.MonkeyPatch, features: dict[str, twoview.SweepFeatures]
) -> None:
    """Should the refinement on the quarter's matches fall short, the early stop
    did not decide: every stage is matched and fitted, as without it."""
    query, known = features["1"], features["1_noise"]
    config = TwoViewConfig(min_inliers=24, accept_share=2.0)
    whole = fit_two_view(query, known, replace(config, accept_share=0.0))
    assert whole is not None
    real = twoview._gauss_newton

    def quarter_fails(residuals: Any, a: np.ndarray, *args: Any) -> np.ndarray | None:
        return None if len(a) < whole.matches else real(residuals, a, *args)

    monkeypatch.setattr(twoview, "_gauss_newton", quarter_fails)
    assert fit_two_view(query, known, config) == whole


@pytest.mark.parametrize("limit", [1, 2])
def test_a_limited_fit_matches_its_stages_and_asks_its_bar_of_them(
    features: dict[str, twoview.SweepFeatures], seen: list[int], limit: int
) -> None:
    """Limited to the first ``limit`` quarters, a fit matches only those, even when
    its first quarter fits clearly, and its inliers count only them; without
    gates too."""
    query, known = features["1"], features["1_noise"]
    config = TwoViewConfig(min_inliers=24, accept_share=2.0, stage_limit=limit)
    fit = fit_two_view(query, known, config)
    taken = sum(len(range(s, len(known), 8)) for s in (0, 4, 1, 5)[: 2 * limit])
    assert sum(seen) == taken
    assert fit is not None and fit.stages == limit
    ungated = replace(config, gate_share=0.0, early_gate_share=0.0)
    seen.clear()
    plain = fit_two_view(query, known, ungated)
    assert sum(seen) == taken
    assert plain is not None and plain.stages == limit and plain.matches == fit.matches
    whole = fit_two_view(query, known, replace(ungated, stage_limit=0))
    assert whole is not None and whole.stages is None and whole.matches > plain.matches


@pytest.mark.parametrize("limit", [1, 2])
def test_a_limited_fits_gates_ask_as_for_every_stage(
    monkeypatch: pytest.MonkeyPatch,
    features: dict[str, twoview.SweepFeatures],
    seen: list[int],
    limit: int,
) -> None:
    """The early gate of a fit limited to ``limit`` quarters and asked ``m``
    inliers asks what a fit of all four asked ``m * 4 / limit`` would: 0.9 of an
    eighth of that. Asked the least ``m`` for which that is 11, a first eighth
    counting 10 stops the fit (unscaled, the count would pass the gate, or there
    would be none, and the fit would go on)."""
    bar = next(m for m in range(1, 200) if int(0.9 * (m * 4 / limit) / (2 * 4)) == 11)
    assert int(0.9 * bar / (2 * 4)) <= 10
    monkeypatch.setattr(stages, "_coarse", lambda *a: (np.array([[10]]), np.zeros(1), [0.0]))
    query, known = features["1"], features["1_noise"]
    config = TwoViewConfig(min_inliers=bar, stage_limit=limit)
    assert fit_two_view(query, known, config) is None
    assert sum(seen) == len(range(0, len(known), 8))


@pytest.mark.parametrize(("q", "k"), PAIRS)
def test_sweeps_off_level_match_every_stage(
    tilted: dict[str, twoview.SweepFeatures], seen: list[int], q: str, k: str
) -> None:
    """Without IMU readings the tilted refinement follows the planar fit, and its
    three more unknowns need every keypoint (on ``3_noise`` against ``3`` a
    quarter's fit was 0.05 rad off): no early stop, whatever the share."""
    config = TwoViewConfig(min_inliers=24, accept_share=2.0)
    fit = fit_two_view(tilted[q], tilted[k], config)
    assert sum(seen) == len(tilted[k])
    assert fit is not None and fit.stages is None
    assert fit == fit_two_view(tilted[q], tilted[k], replace(config, accept_share=0.0))
