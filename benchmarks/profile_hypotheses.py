"""Where competing maps spend a decision's time: ``cProfile`` of the localizer's
decisions during a replay, at the defaults and with one map (``--hypotheses 1``).

    python benchmarks/profile_hypotheses.py LOG [--top T] [--fits]

Replays LOG as ``pipemap score`` does (``api.replay``), twice, with the profiler
on only inside ``Localizer.localize`` (reading the log is left out), and prints
for each run the CPU seconds of the decisions under the profiler, the calls and
cumulative seconds of the steps competing maps add (the two-view fits asked,
``Localizer._fit``, by caller, and those computed, ``candidate_fit``: the rest
were kept from earlier in the visit, :mod:`localizer.fitcache`; the branches; the
maps' copies, visits and planarity test), and the ``T`` functions with most
cumulative time. The profiler's overhead
falls mostly on Python code; ``bench_score.py`` measures the latency itself.

``--fits`` lists every two-view fit asked, visit by visit, at the defaults and
with one map (no profiler): the step that asked it (``_verified``: the choice among
the candidates; ``alike_branches``, ``_repeats``, ``_repeats_far``: the branch), the
junction, the inliers asked and found, whether it was computed or kept from
earlier in the visit, its CPU milliseconds, and the decision that followed (its
junction, the maps alive, the candidates rejected, the look-alikes named); then the
fits computed and their CPU time by step, and the decisions' CPU time with and
without the fits computed (after a first replay, untimed, for what a process
imports on first use).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import cProfile  # noqa: E402
import io  # noqa: E402
import pstats  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402

from pipemap import api  # noqa: E402
from pipemap.allocator import keep_freed_memory  # noqa: E402
from pipemap.localizer import LocalizerConfig, fitcache  # noqa: E402
from pipemap.localizer import localizer as localizer_module  # noqa: E402

cv2.setNumThreads(1)

#: (function name, file name ending) of the steps competing maps add or repeat.
STEPS = (
    ("_verified", "localizer.py"),
    ("fit_once", "fitcache.py"),
    ("candidate_fit", "verify.py"),
    ("_repeats_far", "branching.py"),
    ("alike_branches", "branching.py"),
    ("new_branch", "branching.py"),
    ("_repeats", "branching.py"),
    ("visit", "hypotheses.py"),
    ("_prune", "hypotheses.py"),
    ("embeds_in_plane", "hypotheses.py"),
    ("copy", "topomap.py"),
)


def profiled_replay(log: api.Log, config: LocalizerConfig) -> tuple[pstats.Stats, int]:
    """The profile of every ``localize`` call of one replay of ``log``, and the calls."""
    profiler = cProfile.Profile(time.process_time)
    real = localizer_module.Localizer.localize
    calls = 0

    def localize(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        nonlocal calls
        calls += 1
        profiler.enable()
        try:
            return real(self, *args, **kwargs)
        finally:
            profiler.disable()

    localizer_module.Localizer.localize = localize  # type: ignore[method-assign]
    try:
        api.replay(log, config)
    finally:
        localizer_module.Localizer.localize = real  # type: ignore[method-assign]
    return pstats.Stats(profiler), calls


def report(name: str, stats: pstats.Stats, calls: int, top: int) -> None:
    total = stats.total_tt  # type: ignore[attr-defined]
    print(f"## {name}: {calls} decisions, {total:.2f} s CPU under the profiler")
    table = stats.stats  # type: ignore[attr-defined]
    for func, file_end in STEPS:
        for (path, _line, fname), (_cc, ncalls, _tt, cumtime, callers) in table.items():
            if fname != func or not path.endswith(file_end):
                continue
            print(f"  {func:<16} {ncalls:>5} calls {cumtime:7.2f} s cumulative")
            if func == "fit_once":
                for (c_path, _l, c_name), c_stats in sorted(callers.items()):
                    print(
                        f"    from {Path(c_path).name}:{c_name:<16} {c_stats[1]:>5} calls "
                        f"{c_stats[3]:7.2f} s"
                    )
    out = io.StringIO()
    stats.stream = out  # type: ignore[attr-defined]
    stats.sort_stats("cumulative").print_stats(top)
    lines = [line for line in out.getvalue().splitlines() if line.strip()]
    start = next((i for i, line in enumerate(lines) if "ncalls" in line), len(lines))
    print("\n".join(lines[start:]))


def fit_trace(log: api.Log, config: LocalizerConfig) -> list[str]:
    """One line per two-view fit asked and per decision of one replay of ``log``."""
    lines: list[str] = []
    visit = -1
    real_localize = localizer_module.Localizer.localize
    real_fit = fitcache.VisitFits.fit
    spent: dict[str, list[float]] = {}
    deciding = 0.0

    def localize(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        nonlocal visit, deciding
        visit += 1
        start = time.process_time()
        d = real_localize(self, *args, **kwargs)
        deciding += time.process_time() - start
        rejected = [i for i, _ in d.rejected]
        lines.append(
            f"visit {visit:>3} decided: node {d.node} {'known' if d.known else 'new'}, "
            f"{d.hypotheses} maps, rejected {rejected}, alike {list(d.alike)}"
        )
        return d

    def fit(self, sweep, node, stored, key, compute):  # type: ignore[no-untyped-def]
        asker = sys._getframe(2).f_code.co_name  # fit_once's caller
        computed = False

        def counted():  # type: ignore[no-untyped-def]
            nonlocal computed
            computed = True
            return compute()

        start = time.process_time()
        result = real_fit(self, sweep, node, stored, key, counted)
        ms = (time.process_time() - start) * 1000.0
        found = "-" if result is None else str(result.inliers)
        if computed:
            spent.setdefault(asker, []).append(ms)
        lines.append(
            f"visit {visit:>3}   fit {asker:<15} node {node:>3} asked {key[1]:>3} "
            f"found {found:>4} {'computed' if computed else 'kept    '} {ms:6.1f} ms"
        )
        return result

    localizer_module.Localizer.localize = localize  # type: ignore[method-assign]
    fitcache.VisitFits.fit = fit  # type: ignore[method-assign]
    try:
        api.replay(log, config)
    finally:
        localizer_module.Localizer.localize = real_localize  # type: ignore[method-assign]
        fitcache.VisitFits.fit = real_fit  # type: ignore[method-assign]
    for asker, times in sorted(spent.items()):
        lines.append(f"computed by {asker:<15} {len(times):>3} fits {sum(times):7.1f} ms CPU")
    fitting = sum(sum(times) for times in spent.values())
    lines.append(
        f"decisions {deciding * 1000.0:.1f} ms CPU: fits {fitting:.1f} ms, "
        f"the rest {deciding * 1000.0 - fitting:.1f} ms"
    )
    return lines


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", type=Path)
    parser.add_argument("--top", type=int, default=20)
    parser.add_argument("--fits", action="store_true", help="list every fit asked (see above)")
    args = parser.parse_args()
    keep_freed_memory()  # as pipemap's commands run (pipemap.allocator)
    log = api.open_log(args.log)
    defaults = LocalizerConfig()
    print(f"# {args.log.name}")
    one = replace(defaults, hypotheses=1)
    if args.fits:
        api.replay(log, defaults)  # untimed: what a process imports on first use
    for name, config in (("defaults", defaults), ("--hypotheses 1", one)):
        if args.fits:
            print(f"## {name}: the fits asked")
            print("\n".join(fit_trace(log, config)))
            continue
        stats, calls = profiled_replay(log, config)
        report(name, stats, calls, args.top)
    return 0


if __name__ == "__main__":
    sys.exit(main())
