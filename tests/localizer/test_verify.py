"""One candidate's two-view check at the rotations its ports allow
(:func:`localizer.verify.candidate_fit`), against a fake fit whose answers depend on
the rotation it is guided by; and the half-turn mistake on a stored log it fixes."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pytest

from pipemap import api
from pipemap.localizer import verify
from pipemap.localizer.twoview import SweepFeatures, TwoViewConfig, TwoViewFit
from pipemap.localizer.verify import candidate_fit

PI = math.pi
TOLERANCE = 0.4
RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


@dataclass
class FakeFits:
    """Fits by the turn they are guided to: ``answers`` maps a rotation to the fit
    found there (the fit's inliers must reach ``min_inliers``), ``None`` a fit at any
    rotation. Records each call's guess, bar and whether it searched the azimuth
    peak too."""

    answers: dict[float | None, TwoViewFit]
    calls: list[tuple[float | None, int, bool]] = field(default_factory=list)
    configs: list[TwoViewConfig] = field(default_factory=list)

    def __call__(self, query, known, config, guess=None, cache=None):  # type: ignore[no-untyped-def]
        self.calls.append((guess, config.min_inliers, config.around_peak))
        self.configs.append(config)
        for at, fit in self.answers.items():
            near = at is None if guess is None else at is not None and abs(at - guess) < 0.2
            if near and fit.inliers >= config.min_inliers:
                return fit
        return None


def _fit(rotation: float, inliers: int) -> TwoViewFit:
    return TwoViewFit(rotation, 0.0, inliers, 2 * inliers)


SWEEP = SweepFeatures(np.zeros((0, 3)), np.zeros((0, 32), np.uint8), 0.01)


def _check(
    monkeypatch: pytest.MonkeyPatch,
    fake: FakeFits,
    guess: float,
    rotations: tuple[float, ...] | None,
    agrees: object = None,
    any_rotation: bool = False,
    needed: int = 48,
) -> TwoViewFit | None:
    monkeypatch.setattr(verify, "fit_two_view", fake)

    def agreeing(fit: TwoViewFit) -> bool:
        if agrees is None:
            return True
        return bool(agrees(fit))  # type: ignore[operator]

    return candidate_fit(
        SWEEP, SWEEP, guess, needed, TwoViewConfig(), rotations, agreeing, any_rotation, TOLERANCE
    )


def test_a_cross_half_a_turn_off_is_turned_back(monkeypatch: pytest.MonkeyPatch) -> None:
    """The junction the map expects (24 inliers needed): the NCC's turn fits 41
    keypoints, the true turn (half a turn on) 51. The other turns a cross allows are
    tried, each asked for more than the fit at hand, and only around its own
    rotation."""
    fake = FakeFits({0.0: _fit(0.01, 41), PI: _fit(PI - 0.02, 51)})
    cross = (0.0, PI / 2, PI, -PI / 2)
    got = _check(monkeypatch, fake, 0.0, cross, needed=24)
    assert got == _fit(PI - 0.02, 51)
    assert fake.calls[0] == (0.0, 24, True)
    assert [c[0] for c in fake.calls[1:]] == [PI / 2, PI, -PI / 2]
    assert fake.calls[1] == (PI / 2, 42, False)
    assert fake.calls[3] == (-PI / 2, 52, False)  # then more than the 51 found


def test_another_turn_with_fewer_keypoints_or_the_same_turn_with_more_does_not_win(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    fewer = FakeFits({0.0: _fit(0.0, 80), PI: _fit(PI, 60)})
    assert _check(monkeypatch, fewer, 0.0, (0.0, PI)) == _fit(0.0, 80)
    # A fit guided to a turn that lands on the turn at hand is no news.
    same = FakeFits({0.0: _fit(0.0, 80), PI: _fit(0.1, 90)})
    assert _check(monkeypatch, same, 0.0, (0.0, PI)) == _fit(0.0, 80)


def test_a_fit_of_the_first_quarter_is_rivalled_on_as_many_keypoints(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The guided fit stopped after the first quarter of the candidate's keypoints
    (119 inliers of it): each other turn of a cross is fitted on that quarter too,
    asked one inlier more, and does not stop early on its own. A fit of every
    keypoint is rivalled on every keypoint, as before."""
    cross = (0.0, PI / 2, PI, -PI / 2)
    quarter = replace(_fit(0.0, 119), stages=1)
    fake = FakeFits({0.0: quarter})
    assert _check(monkeypatch, fake, 0.0, cross) == quarter
    first, *rivals = fake.configs
    assert (first.stage_limit, first.accept_share) == (0, TwoViewConfig().accept_share)
    assert len(rivals) == 3
    assert all((c.stage_limit, c.accept_share, c.min_inliers) == (1, 0.0, 120) for c in rivals)
    fake = FakeFits({0.0: _fit(0.0, 400)})
    _check(monkeypatch, fake, 0.0, cross)
    assert [(c.stage_limit, c.accept_share, c.min_inliers) for c in fake.configs[1:]] == [
        (0, 0.0, 401)
    ] * 3


def test_a_tee_whose_guided_fit_passed_costs_no_other_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    fake = FakeFits({0.3: _fit(0.3, 200)})
    assert _check(monkeypatch, fake, 0.3, (0.35,)) == _fit(0.3, 200)
    assert len(fake.calls) == 1


def test_a_failed_guided_fit_is_tried_at_the_turns_the_ports_allow(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The NCC was a quarter turn off: the T's one allowed turn is tried (and a turn
    beside the failed guess is not tried again)."""
    fake = FakeFits({PI / 2: _fit(PI / 2, 120)})
    assert _check(monkeypatch, fake, 0.0, (PI / 2,)) == _fit(PI / 2, 120)
    assert [c[0] for c in fake.calls] == [0.0, PI / 2]
    fake = FakeFits({})
    assert _check(monkeypatch, fake, 0.0, (0.1,)) is None
    assert [c[0] for c in fake.calls] == [0.0]


def test_pipes_that_cannot_line_up_ask_for_no_other_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    fake = FakeFits({PI: _fit(PI, 120)})
    assert _check(monkeypatch, fake, 0.0, (), any_rotation=True) is None
    assert [c[0] for c in fake.calls] == [0.0]


@pytest.mark.parametrize("lamp", [True, False])
def test_without_ports_only_the_lamp_fits_again_at_any_rotation(
    monkeypatch: pytest.MonkeyPatch, lamp: bool
) -> None:
    fake = FakeFits({None: _fit(PI / 2, 120)})
    got = _check(monkeypatch, fake, 0.0, None, any_rotation=lamp)
    assert (got == _fit(PI / 2, 120)) is lamp
    assert [c[0] for c in fake.calls] == ([0.0, None] if lamp else [0.0])


def test_a_turn_the_ports_refuse_yields_to_one_they_allow(monkeypatch: pytest.MonkeyPatch) -> None:
    """The guided fit's turn does not line the exits up: an allowed turn that fits
    with the inliers needed is taken instead, however many the refused one had; with
    none, the refused fit is returned, for the port check to pass it over and say
    why."""
    refused = _fit(0.0, 300)

    def agrees(fit: TwoViewFit) -> bool:
        return abs(fit.rotation_rad) > 1.0

    fake = FakeFits({0.0: refused, PI: _fit(PI, 60)})
    assert _check(monkeypatch, fake, 0.0, (PI,), agrees) == _fit(PI, 60)
    assert fake.calls[1] == (PI, 48, False)
    fake = FakeFits({0.0: refused})
    assert _check(monkeypatch, fake, 0.0, (PI,), agrees) == refused


def test_the_stored_active_log_has_no_revisit_half_a_turn_off() -> None:
    """``paper_active`` (96 px): at cross C the NCC and the fit at its turn were half
    a turn off (3.107 rad), and the arrival mapped onto the wrong port (a conflict in
    the map). Every revisit is now within 0.05 rad, and the map has no conflict."""
    log = api.open_log(RECORDINGS / "paper_active.mcap")
    report = api.score(log)
    errors = [abs(v.rotation_error_rad) for v in report.visits if v.rotation_error_rad is not None]
    assert len(errors) == 6 and max(errors) < 0.05
    assert all(v["conflict"] is None for v in api.replay(log).document()["visits"])


@pytest.mark.parametrize("verify_rule", [True, False])
def test_both_rules_fit_at_the_turns_the_ports_allow(
    monkeypatch: pytest.MonkeyPatch, verify_rule: bool
) -> None:
    """Whether the two-view check decides (the default) or only measures the
    rotation (``--no-verify``), a revisit's fit is the candidate's fit at the turns
    its ports allow: a cross revisited half a turn off (the fake fits the turn the
    guess is not at) gets the other turn's rotation, and its exits the other ports."""
    from pipemap.localizer import Localizer, LocalizerConfig
    from pipemap.localizer.twoview import TwoViewFit as Fit
    from tests.localizer.junctions import junction

    cross = (PI, PI / 2, 0.0, -PI / 2)

    def half_turn_off(query, known, config, guess=None, cache=None):  # type: ignore[no-untyped-def]
        near_half = guess is not None and abs(abs(guess) - PI) < 0.3
        return Fit(PI, 0.0, 300, 400) if near_half else None

    monkeypatch.setattr(verify, "fit_two_view", half_turn_off)
    loc = Localizer(LocalizerConfig(verify=verify_rule, active_vision=False))
    loc.localize(junction(0), exits_rad=cross)
    loc.depart(0.0)
    loc.localize(junction(1), exits_rad=(PI, 0.0))
    loc.depart(PI)
    d = loc.localize(junction(0), exits_rad=cross)  # the same images: the NCC says 0
    assert d.known and d.node == 0
    assert d.two_view is not None and abs(abs(d.two_view.rotation_rad) - PI) < 1e-9
    assert d.exit_ports == (2, 3, 0, 1)  # behind is now the first visit's ahead
