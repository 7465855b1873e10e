"""Metadata values back to their types (MCAP metadata holds strings only)."""

from __future__ import annotations

import pytest

from pipemap.recorder.metadata import lamp_strength, typed_metadata


def test_known_keys_parse_and_the_rest_stay_text() -> None:
    record = {
        "network": "grid:3x3",
        "seed": "7",
        "threshold": "0.36",
        "align_sweeps": "false",
        "simulator": '{"camera": {"fov_rad": 1.4}}',
        "status": "finished",
        "sweeps": "13",
    }
    assert typed_metadata(record) == {
        "network": "grid:3x3",
        "seed": 7,
        "threshold": 0.36,
        "align_sweeps": False,
        "simulator": {"camera": {"fov_rad": 1.4}},
        "status": "finished",
        "sweeps": 13,
    }


def test_a_value_that_does_not_parse_stays_visible() -> None:
    record = {"seed": "seven", "align_sweeps": "yes", "simulator": "{broken"}
    assert typed_metadata(record) == record


@pytest.mark.parametrize(
    ("simulator", "strength"),
    [
        ('{"camera": {"lamp_strength": 0.5}}', 0.5),
        ('{"camera": {"lamp_strength": 0.0}}', 0.0),
        ('{"camera": {"fov_rad": 1.4}}', 0.0),  # before the lamp was recorded
        ('{"camera": {"lamp_strength": "bright"}}', 0.0),
        ("{broken", 0.0),
        (None, 0.0),
    ],
)
def test_the_lamp_strength_of_a_run(simulator: str | None, strength: float) -> None:
    record = {} if simulator is None else {"simulator": simulator}
    assert lamp_strength(record) == strength
