"""The golden path: every stored log in ``recordings/`` replays and scores as committed.

A change to the localizer that changes a decision, a similarity or a rotation on
these logs fails here; if the change is meant, regenerate the expected files as
``recordings/README.md`` says and commit them with the change.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from pipemap.replay import FileSource, replay, score_replay

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"
LOGS = sorted(p.stem for p in RECORDINGS.glob("*.mcap"))
#: Numbers are stored to 6 decimals; one unit of the last place either way is allowed.
TOLERANCE = 1.5e-6
#: Fields that name the file or time the machine, not the result.
NOT_COMPARED = {"log", "latency_ms"}


def assert_same(expected: Any, actual: Any, where: str = "") -> None:
    """Equal structure and values, floats within ``TOLERANCE``."""
    if isinstance(expected, dict):
        assert isinstance(actual, dict), where
        assert sorted(expected) == sorted(actual), f"{where}: keys differ"
        for key in expected:
            assert_same(expected[key], actual[key], f"{where}.{key}")
    elif isinstance(expected, list):
        assert isinstance(actual, list) and len(actual) == len(expected), f"{where}: length"
        for i, (e, a) in enumerate(zip(expected, actual, strict=True)):
            assert_same(e, a, f"{where}[{i}]")
    elif isinstance(expected, float) and not isinstance(actual, bool):
        assert isinstance(actual, int | float), f"{where}: {actual!r} is not a number"
        assert math.isclose(expected, actual, rel_tol=0.0, abs_tol=TOLERANCE), (
            f"{where}: {actual} != {expected}"
        )
    else:
        assert expected == actual, f"{where}: {actual!r} != {expected!r}"


def test_the_three_kinds_of_stored_log_are_there() -> None:
    assert LOGS == ["paper_active", "paper_autonomous", "random8_loops"]
    for name in LOGS:
        assert (RECORDINGS / f"{name}.mcap").stat().st_size <= 6 * 1024 * 1024
        assert (RECORDINGS / f"{name}.map.json").is_file()
        assert (RECORDINGS / f"{name}.score.json").is_file()


@pytest.mark.parametrize("name", LOGS)
def test_a_stored_log_replays_and_scores_as_committed(name: str) -> None:
    assert_replays_as_committed(name)


def assert_replays_as_committed(name: str) -> None:
    """Replay and score the stored log ``name``; both as its committed files say."""
    source = FileSource(RECORDINGS / f"{name}.mcap")
    result = replay(source)
    expected_map = json.loads((RECORDINGS / f"{name}.map.json").read_text())
    assert_same(expected_map, result.document(), "map")
    report = score_replay(result, source, 0.36)
    expected = json.loads((RECORDINGS / f"{name}.score.json").read_text())
    actual = report.document(with_latency=False)
    assert_same(
        {k: v for k, v in expected.items() if k not in NOT_COMPARED},
        {k: v for k, v in actual.items() if k not in NOT_COMPARED},
        "score",
    )
