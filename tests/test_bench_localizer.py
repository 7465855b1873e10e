"""``benchmarks/bench_localizer.py --json``: what its decision timings measure.

The benchmark's numbers go in the README; this checks the method, not the times: a
cold try rebuilds its candidates' refinement spectra, a warm one finds them cached.
"""

from __future__ import annotations

import importlib.util
import sys
from collections.abc import Iterator
from pathlib import Path
from types import ModuleType

import pytest

from tests.conftest import REPO, PaperSet


@pytest.fixture(scope="module")
def bench() -> Iterator[ModuleType]:
    """The benchmark as a module. Its import holds OpenCV to one thread, as the
    benchmark measures; the worker's other tests get their threads back after."""
    import cv2

    threads = cv2.getNumThreads()
    path = REPO / "benchmarks" / "bench_localizer.py"
    spec = importlib.util.spec_from_file_location("bench_localizer_under_test", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        cv2.setNumThreads(threads)


def test_cold_tries_rebuild_the_candidates_spectra_and_warm_ones_do_not(
    bench: ModuleType, paper_sets: dict[str, PaperSet]
) -> None:
    sets = {name: paper_sets[name].images for name in sorted(paper_sets)[:3]}
    result = bench.decision_benchmark(sets, [4], px=96, repeat=2)
    # Two refined candidates a decision (FastConfig.refine_candidates), every cold try.
    assert result["rebuilds_per_decision"] == {"warm": 0.0, "cold": 2.0}
    assert set(result["decision_cold_ms"]) == set(result["decision_ms"]) == {"4"}
    assert result["known"] == 0 and result["two_view"] is True
    assert Path(bench.__file__).name == "bench_localizer.py"


def test_the_memory_parts_add_up_to_what_a_junction_keeps(
    bench: ModuleType, paper_sets: dict[str, PaperSet]
) -> None:
    sets = {name: paper_sets[name].images for name in sorted(paper_sets)[:3]}
    result = bench.decision_benchmark(sets, [4], px=96, repeat=1)
    parts = dict(result["memory_parts_kib"])
    assert parts.pop("keypoints_per_junction") > 0
    assert min(parts.values()) >= 0 and parts["keypoint_descriptors"] > 0
    # Each part rounded to 0.01 KiB, the whole to 0.1.
    assert sum(parts.values()) == pytest.approx(result["memory_per_junction_kib"], abs=0.1)
