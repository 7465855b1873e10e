"""Tests of :mod:`localizer.phases`: a decision's time, charged phase by phase by a
clock the caller gives the localizer. The clock here is a fake one that only moves
when a phase's own work runs, so each phase's total says exactly whose work it was
charged with."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import pytest

from pipemap.localizer import localizer as localizer_module
from pipemap.localizer.decision import ProbeKind
from pipemap.localizer.fastmatch import FastMatcher
from pipemap.localizer.localizer import PAPER, Localizer, LocalizerConfig
from pipemap.localizer.phases import PHASES, PhaseClock
from pipemap.localizer.topomap import TopoMap
from tests.localizer.junctions import STRICT, FakeProbes, junction


class FakeClock:
    """Seconds that pass only when :meth:`spend` says so."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now

    def spend(self, seconds: float) -> None:
        self.now += seconds


def _costing(
    monkeypatch: pytest.MonkeyPatch, owner: Any, name: str, clock: FakeClock, seconds: float
) -> None:
    """Make ``owner.name`` take ``seconds`` on ``clock`` each time it runs."""
    real = getattr(owner, name)

    def costly(*args: Any, **kwargs: Any) -> Any:
        clock.spend(seconds)
        return real(*args, **kwargs)

    monkeypatch.setattr(owner, name, costly)


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> FakeClock:
    """A fake clock that each phase's own work moves by its own amount: the NCC's
    preparation 1 s and matching 2 s, ORB 10 s, the check 100 s, the map 1000 s."""
    fake = FakeClock()
    _costing(monkeypatch, FastMatcher, "prepare", fake, 1.0)
    _costing(monkeypatch, FastMatcher, "match", fake, 2.0)
    _costing(monkeypatch, localizer_module, "stored_features", fake, 10.0)
    _costing(monkeypatch, Localizer, "_verified", fake, 100.0)
    _costing(monkeypatch, localizer_module, "threshold_candidates", fake, 100.0)
    _costing(monkeypatch, TopoMap, "visit", fake, 1000.0)
    return fake


def test_each_phase_is_charged_with_its_own_work(clock: FakeClock) -> None:
    loc = Localizer(clock=clock)
    for seed in (0, 1, 0):  # new, new, a revisit
        loc.localize(junction(seed))
        assert loc.last_phases == {"ncc": 3.0, "keypoints": 10.0, "check": 100.0, "map": 1000.0}
    assert tuple(loc.last_phases) == PHASES


def test_without_the_two_view_check_no_time_goes_to_keypoints(clock: FakeClock) -> None:
    loc = Localizer(PAPER, clock=clock)
    loc.localize(junction(0))
    loc.localize(junction(0))
    assert loc.last_phases == {"ncc": 3.0, "keypoints": 0.0, "check": 100.0, "map": 1000.0}


def test_a_probes_new_junction_charges_the_visits_own_keypoints_to_keypoints(
    clock: FakeClock,
) -> None:
    # A probe improves on the visit's sweep but not to the threshold: the junction is
    # new and keeps the visit's own sweep's keypoints, computed after the decision.
    loc = Localizer(replace(LocalizerConfig(), threshold=STRICT, verify=False), clock=clock)
    loc.localize(junction(0))
    loc.localize(junction(1))
    query = junction(0, noise=1.0)
    better = junction(0, noise=0.8, noise_seed=5)
    d = loc.localize(query, FakeProbes({ProbeKind.ROTATE: better}))
    assert not d.known and d.probes[0].improved
    # Two sweeps prepared and matched (the visit's and the probe's); ORB on both.
    assert loc.last_phases == {"ncc": 6.0, "keypoints": 20.0, "check": 100.0, "map": 1000.0}


def test_without_a_clock_nothing_is_timed() -> None:
    loc = Localizer()
    loc.localize(junction(0))
    assert loc.last_phases == {}
    timer = PhaseClock(None)
    timer.lap("ncc")
    assert timer.seconds == {}
