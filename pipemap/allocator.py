"""Keeping freed memory for reuse: glibc's allocator set up for numpy's temporaries.

The matcher makes many short-lived arrays of a few hundred KiB to a few MiB (FFT
products, window sums, Hamming distances). glibc serves them by ``mmap`` or by
growing the heap and hands the pages back as soon as they are freed, so the next
array of the same size faults every page in again. Measured (issue 17, stop 30;
docs/performance.md) with ``benchmarks/bench_score.py`` on the 400 px ``paper``
log: 13.1-13.9 ms a decision with ``--no-two-view``, 8.2-8.7 so set up; 26.8-27.8
at the defaults, 22.1-23.7. Against 1000 known junctions
(``benchmarks/bench_localizer.py --json``) 41-44 ms, 36-38. At 200 px (smaller
arrays) no difference was measured.

:func:`keep_freed_memory` raises the ``mmap`` threshold to 32 MiB (glibc's own
ceiling when it adapts it) and keeps 64 MiB at the top of the heap when it trims:
a process keeps up to that much more than it uses, and finds it again without a
fault. Commands call it first (``pipemap.cli``), as does each batch worker
(``pipemap.batch``); a script using :mod:`pipemap.api` may call it too. Results do
not depend on it, only the time they take.

Standard library only, and nothing of pipemap: every layer may run under it.
"""

from __future__ import annotations

import ctypes
import os
import sys

__all__ = ["MMAP_THRESHOLD_BYTES", "TOP_PAD_BYTES", "keep_freed_memory"]

#: Blocks at least this large are mapped and unmapped on their own (glibc's default
#: starts at 128 KiB and adapts up to 32 MiB on 64-bit systems).
MMAP_THRESHOLD_BYTES = 32 << 20
#: Free memory kept at the top of the heap when it shrinks, and added when it grows.
TOP_PAD_BYTES = 64 << 20

# mallopt(3) parameters (malloc.h).
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3

#: Environment variables by which a user sets glibc's allocator up themselves.
_USER_SETTINGS = ("MALLOC_TOP_PAD_", "MALLOC_TRIM_THRESHOLD_", "MALLOC_MMAP_THRESHOLD_")


def keep_freed_memory() -> bool:
    """Set glibc's allocator up to keep freed memory for reuse (see the module).

    Returns whether it did: ``False`` off Linux with glibc, and where the
    environment already sets the allocator (``MALLOC_TOP_PAD_``,
    ``MALLOC_TRIM_THRESHOLD_``, ``MALLOC_MMAP_THRESHOLD_`` or a ``glibc.malloc``
    tunable in ``GLIBC_TUNABLES``): the user's settings stand.
    """
    if not sys.platform.startswith("linux") or not _glibc():
        return False
    if any(name in os.environ for name in _USER_SETTINGS):
        return False
    if "glibc.malloc." in os.environ.get("GLIBC_TUNABLES", ""):
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
    except OSError:
        return False
    # Raising the threshold first: setting either stops glibc adapting it.
    return bool(
        libc.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
        and libc.mallopt(_M_TOP_PAD, TOP_PAD_BYTES) == 1
    )


def _glibc() -> bool:
    """Whether this process runs on glibc (``confstr`` answers only there)."""
    try:
        version = os.confstr("CS_GNU_LIBC_VERSION")
    except (ValueError, OSError):
        return False
    return bool(version) and str(version).startswith("glibc")
