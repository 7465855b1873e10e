"""Fixtures of the localizer's tests."""

from __future__ import annotations

import numpy as np
import pytest

from pipemap.localizer import keymatch


@pytest.fixture
def seen(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """How many keypoints of the known sweep each Hamming matching took."""
    counts: list[int] = []
    real = keymatch._word_ratio_matches

    def counting(words_a: np.ndarray, b: np.ndarray, ratio: float) -> tuple[np.ndarray, np.ndarray]:
        counts.append(len(b))
        return real(words_a, b, ratio)

    monkeypatch.setattr(keymatch, "_word_ratio_matches", counting)
    return counts
