"""The matcher's transforms are scipy.fft's to the last bit, without importing it."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy import fft as scipy_fft

from pipemap.localizer import transforms


def _arrays() -> list[np.ndarray]:
    rng = np.random.default_rng(3)
    real = rng.standard_normal((3, 10, 12)).astype(np.float32)
    return [real, real.astype(np.float64), real.transpose(1, 2, 0)]


def test_the_compiled_module_is_used_here() -> None:
    # If it stopped loading, every command would pay scipy.fft's import again.
    assert transforms.backend() == "pocketfft"


@pytest.mark.parametrize("n", [None, 7, 12, 25])
@pytest.mark.parametrize("axis", [0, 1, -1])
def test_real_and_complex_transforms_equal_scipy_fft_bit_for_bit(n: int | None, axis: int) -> None:
    for x in _arrays():
        expected = scipy_fft.rfft(x, n=n, axis=axis)
        got = transforms.rfft(x, n=n, axis=axis)
        assert got.dtype == expected.dtype and np.array_equal(got, expected)
        spectrum = scipy_fft.fft(expected, n=n, axis=(axis + 1) % 3 - 1)
        for name in ("fft", "ifft"):
            want = getattr(scipy_fft, name)(spectrum, n=n, axis=axis)
            have = getattr(transforms, name)(spectrum, n=n, axis=axis)
            assert have.dtype == want.dtype and np.array_equal(have, want), name
        want = scipy_fft.irfft(spectrum, n=n, axis=axis)
        have = transforms.irfft(spectrum, n=n, axis=axis)
        assert have.dtype == want.dtype and np.array_equal(have, want)


def test_without_the_compiled_module_scipy_fft_answers(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(transforms, "_pocketfft", lambda: None)
    assert transforms.backend() == "scipy.fft"
    x = _arrays()[0]
    assert np.array_equal(transforms.rfft(x, n=16, axis=2), scipy_fft.rfft(x, n=16, axis=2))
    spectrum = scipy_fft.rfft(x, axis=2)
    assert np.array_equal(transforms.irfft(spectrum, n=12), scipy_fft.irfft(spectrum, n=12))
    assert np.array_equal(transforms.ifft(spectrum, axis=1), scipy_fft.ifft(spectrum, axis=1))


def test_matching_sets_does_not_import_scipy_fft() -> None:
    code = (
        "import sys, numpy as np\n"
        "from pipemap.localizer import ImageSet, pairwise_matches\n"
        "rng = np.random.default_rng(0)\n"
        "sets = [ImageSet(rng.integers(0, 255, (6, 64, 64), dtype=np.uint8)) for _ in range(3)]\n"
        "assert len(pairwise_matches(sets)) == 3\n"
        "print(sorted(m for m in sys.modules if m.startswith('scipy.fft')))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], check=True, capture_output=True, text=True
    ).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("axis", [1, 2])
def test_transforms_into_a_given_array_give_the_same_bits(axis: int) -> None:
    spectrum = scipy_fft.fft(scipy_fft.rfft(_arrays()[0], axis=2), axis=1)
    want = scipy_fft.ifft(spectrum, axis=axis)
    into = np.full_like(want, np.nan)
    assert transforms.ifft(spectrum, axis=axis, out=into) is into
    assert np.array_equal(into, want)
    in_place = spectrum.copy()  # the matcher transforms its pair spectra in place
    assert np.array_equal(transforms.ifft(in_place, axis=axis, out=in_place), want)
    rows = spectrum[:, :7]  # a strided view, as the matcher's kept rows are
    want_real = scipy_fft.irfft(rows, n=20, axis=2)
    real_out = np.full(want_real.shape, np.nan, dtype=want_real.dtype)
    assert transforms.irfft(rows, n=20, axis=2, out=real_out) is real_out
    assert np.array_equal(real_out, want_real)


def test_scipy_fft_answers_into_a_given_array(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(transforms, "_pocketfft", lambda: None)
    spectrum = scipy_fft.rfft(_arrays()[0], axis=2)
    into = np.empty_like(spectrum)
    assert transforms.ifft(spectrum, axis=1, out=into) is into
    assert np.array_equal(into, scipy_fft.ifft(spectrum, axis=1))
    real_out = np.empty((3, 10, 12), dtype=np.float32)
    assert transforms.irfft(spectrum, n=12, out=real_out) is real_out
    assert np.array_equal(real_out, scipy_fft.irfft(spectrum, n=12))
