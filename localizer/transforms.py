"""The matcher's four FFTs, by scipy's pocketfft without importing ``scipy.fft``.

``import scipy.fft`` costs every command that matches 0.2-0.5 s of CPU (it brings in
scipy's array-API layer, ``scipy.special`` and ``numpy.f2py``), more than the
transforms of a pair of 800 px sets. The transforms themselves live in one compiled
module of scipy's, ``scipy/fft/_pocketfft/pypocketfft``, which needs nothing of
scipy to load. It is loaded here from scipy's installed files, and :func:`rfft`,
:func:`fft`, :func:`ifft` and :func:`irfft` call it exactly as ``scipy.fft``'s
functions of the same name do with their default norm and one worker (zero padding
or truncation to ``n`` along ``axis``, then the one-axis transform): the same calls,
so the same bits (``tests/localizer/test_transforms.py`` checks both ways). If the
compiled module cannot be found or loaded, ``scipy.fft`` itself is used.
"""

from __future__ import annotations

import functools
import importlib.machinery
import importlib.util
from types import ModuleType
from typing import Any

import numpy as np

__all__ = ["backend", "fft", "ifft", "irfft", "rfft"]

#: Normalization codes of pocketfft: 0 none (forward), 2 divide by n (inverse).
_FORWARD_NORM, _INVERSE_NORM = 0, 2


@functools.cache
def _pocketfft() -> Any:
    """The compiled pocketfft module of the installed scipy, or None."""
    try:
        spec = importlib.util.find_spec("scipy")  # finds the package, does not run it
        if spec is None or not spec.submodule_search_locations:
            return None
        package = next(iter(spec.submodule_search_locations))
        # The import system's own finder for extension modules, in scipy's folder.
        finder = importlib.machinery.FileFinder(
            f"{package}/fft/_pocketfft",
            (importlib.machinery.ExtensionFileLoader, importlib.machinery.EXTENSION_SUFFIXES),
        )
        found = finder.find_spec("scipy.fft._pocketfft.pypocketfft")
        if found is None or found.loader is None:
            return None
        module = importlib.util.module_from_spec(found)
        found.loader.exec_module(module)
    except (ImportError, OSError):
        return None
    return module if all(hasattr(module, f) for f in ("c2c", "r2c", "c2r")) else None


def _scipy_fft() -> ModuleType:
    from scipy import fft

    module: ModuleType = fft
    return module


def backend() -> str:
    """Which implementation the transforms use: ``"pocketfft"`` or ``"scipy.fft"``."""
    return "pocketfft" if _pocketfft() is not None else "scipy.fft"


def _floating(x: np.ndarray) -> np.ndarray:
    """``x`` as scipy.fft reads it: native byte order, aligned, float or complex."""
    if x.dtype == np.float16:
        return np.asarray(x, np.float32)
    if x.dtype.kind not in "fc":
        return np.asarray(x, np.float64)
    copy = None if x.flags["ALIGNED"] else True
    return np.array(x, dtype=x.dtype.newbyteorder("="), copy=copy)


def _sized(x: np.ndarray, n: int, axis: int) -> np.ndarray:
    """``x`` cut or zero-padded to ``n`` along ``axis``, as scipy.fft does."""
    if n < 1:
        raise ValueError(f"invalid number of data points ({n}) specified")
    index: list[slice] = [slice(None)] * x.ndim
    if x.shape[axis] >= n:
        index[axis] = slice(0, n)
        return x[tuple(index)]
    index[axis] = slice(0, x.shape[axis])
    shape = list(x.shape)
    shape[axis] = n
    padded = np.zeros(shape, x.dtype)
    padded[tuple(index)] = x
    return padded


def rfft(x: np.ndarray, n: int | None = None, axis: int = -1) -> np.ndarray:
    """``scipy.fft.rfft(x, n, axis)``."""
    pocket = _pocketfft()
    if pocket is None:
        return np.asarray(_scipy_fft().rfft(x, n=n, axis=axis))
    data = _floating(x)
    if data.dtype.kind == "c":
        raise TypeError("x must be a real sequence")
    if n is not None:
        data = _sized(data, n, axis)
    return np.asarray(pocket.r2c(data, (axis,), True, _FORWARD_NORM, None, 1))


def _into(result: np.ndarray, out: np.ndarray | None) -> np.ndarray:
    """``result``, written into ``out`` if given (scipy.fft's path has no ``out``)."""
    if out is None:
        return result
    out[...] = result
    return out


def _c2c(
    forward: bool, x: np.ndarray, n: int | None, axis: int, out: np.ndarray | None
) -> np.ndarray:
    pocket = _pocketfft()
    if pocket is None:
        module = _scipy_fft()
        result = (module.fft if forward else module.ifft)(x, n=n, axis=axis)
        return _into(np.asarray(result), out)
    data = _floating(x)
    if n is not None:
        data = _sized(data, n, axis)
    norm = _FORWARD_NORM if forward else _INVERSE_NORM
    return np.asarray(pocket.c2c(data, (axis,), forward, norm, out, 1))


def fft(x: np.ndarray, n: int | None = None, axis: int = -1) -> np.ndarray:
    """``scipy.fft.fft(x, n, axis)``."""
    return _c2c(True, x, n, axis, None)


def ifft(
    x: np.ndarray, n: int | None = None, axis: int = -1, out: np.ndarray | None = None
) -> np.ndarray:
    """``scipy.fft.ifft(x, n, axis)``, written into ``out`` if given (its shape and
    complex type; it may be ``x`` itself)."""
    return _c2c(False, x, n, axis, out)


def irfft(
    x: np.ndarray, n: int | None = None, axis: int = -1, out: np.ndarray | None = None
) -> np.ndarray:
    """``scipy.fft.irfft(x, n, axis)``, written into ``out`` if given (its shape and
    real type)."""
    pocket = _pocketfft()
    if pocket is None:
        return _into(np.asarray(_scipy_fft().irfft(x, n=n, axis=axis)), out)
    data = _floating(x)
    if data.dtype.kind != "c":
        data = data + 0.0j
    if n is None:
        n = (data.shape[axis] - 1) * 2
        if n < 1:
            raise ValueError(f"invalid number of data points ({n}) specified")
    else:
        data = _sized(data, n // 2 + 1, axis)
    return np.asarray(pocket.c2r(data, (axis,), n, False, _INVERSE_NORM, out, 1))
