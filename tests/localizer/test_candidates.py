"""The two-view check's candidates among many known junctions, most of them left out
of the screen by the index: the order of checking every known junction, found
without a pass over each of them."""

from __future__ import annotations

import numpy as np
import pytest

from pipemap.localizer import Localizer, LocalizerConfig
from pipemap.localizer.decision import best_candidate, check_order
from pipemap.localizer.fastmatch import UNSCREENED, Shortlisted
from pipemap.localizer.similarity import SetMatch

KNOWN = 2000


def _match(similarity: float, refined: bool) -> SetMatch:
    return SetMatch(similarity, 0, 0.0, 0.0, 0.0, refined=refined)


def _exhaustive(matches: list[SetMatch], allowed: set[int], count: int) -> list[int]:
    """The candidates as the check once ranked them: every allowed junction sorted."""
    ranked = sorted(
        (i for i in range(len(matches)) if i in allowed),
        key=lambda i: (not matches[i].refined, -matches[i].similarity, i),
    )
    return ranked[:count]


@pytest.mark.parametrize("near_share", [1.0, 0.05, 0.0])
def test_the_candidates_are_the_best_allowed_of_every_known_junction(
    near_share: float, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With most junctions unscreened and some screened ones ruled out by odometry
    (all of them, with ``near_share`` 0: then the unscreened fill in, in node order),
    the junctions fitted are the exhaustive ranking's, and the allowed test runs on
    a few junctions beyond the screened, not on all."""
    rng = np.random.default_rng(3)
    matches = [UNSCREENED] * KNOWN
    screened = sorted(rng.choice(KNOWN, 70, replace=False).tolist())
    for rank, i in enumerate(screened):
        matches[i] = _match(float(rng.uniform(-0.5, 0.9)), refined=rank % 9 == 0)
    near = set(range(KNOWN)) - {i for i in screened if rng.random() >= near_share}
    localizer = Localizer(LocalizerConfig())
    asked: list[int] = []
    fitted: list[int] = []

    def is_near(i: int) -> bool:
        asked.append(i)
        return i in near

    monkeypatch.setattr(localizer._odometry, "near", is_near)
    # No ports to compare, and no id of the pool to leave unused: the map of this
    # test has no nodes.
    monkeypatch.setattr(localizer, "_allowed_rotations", lambda *args: None)
    monkeypatch.setattr(localizer.map, "unused", lambda i: False)
    monkeypatch.setattr(localizer, "_fit", lambda i, *args: fitted.append(i))
    rejected: list[tuple[int, str]] = []
    assert localizer._verified(None, matches, 0.0, None, rejected) is None  # type: ignore[arg-type]
    expected = _exhaustive(matches, near, localizer.config.verify_candidates)
    assert fitted == expected
    assert len(asked) <= len(screened) + localizer.config.verify_candidates


def test_a_shortlisted_list_gives_the_choice_and_candidates_of_a_pass_over_every_junction() -> None:
    """The matcher's list names its screened junctions (:class:`Shortlisted`); the best
    candidate, its margin and the check's candidates found from them are those of a
    pass over every known junction, whatever is excluded."""
    rng = np.random.default_rng(5)
    plain = [UNSCREENED] * KNOWN
    screened = sorted(rng.choice(KNOWN, 70, replace=False).tolist())
    for rank, i in enumerate(screened):
        plain[i] = _match(float(rng.uniform(-0.5, 0.9)), refined=rank % 9 == 0)
    named = Shortlisted(plain)
    named.screened = screened
    refined = [i for i in screened if plain[i].refined]
    allowed = set(rng.choice(KNOWN, KNOWN // 2, replace=False).tolist())
    for exclude in (None, refined[0], screened[1]):
        assert best_candidate(named, exclude) == best_candidate(plain, exclude)
    assert best_candidate(named)[0] in refined
    assert check_order(named, allowed.__contains__, 4) == check_order(
        plain, allowed.__contains__, 4
    )
    assert check_order(named, allowed.__contains__, 4)[1] == screened
