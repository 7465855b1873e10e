"""Known/new decisions of the paper's similarity and of pipemap's robust one, by threshold.

    pipemap sim --network paper --condition noise --seed 0 --save-sweeps runs/noise_s0
    ...
    python benchmarks/eval_similarity.py runs/* [--thresholds 0.26:0.40:0.01]

Each argument is a folder written by ``pipemap sim --save-sweeps`` (sweeps in visit
order, the true node in each ``info.txt``). Every run is localized visit by visit,
as ``pipemap map`` does (no probes), once per threshold, with:

* ``paper``: the paper's Algorithm 2 (the default);
* ``zoom+highpass``: ``--zoom 1.15,1.3 --highpass 0.175``;
* ``robust``: ``--robust`` (``--zoom 1.15,1.3 --highpass 0.125 --baseline``; its
  scores sit near 0, so give it thresholds like ``--thresholds 0.04:0.09:0.005``).

A decision is wrong if a new junction is declared known, or a revisit is not
matched to its junction's node. Prints wrong decisions per threshold, in total and
by run. The truth is read only here, to score; the localizer never sees it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from pipemap.imagesets import load_image_sets, read_info
from pipemap.localizer import FastConfig, ImageSet, Localizer, LocalizerConfig
from pipemap.localizer.presets import ROBUST_FAST, ROBUST_HIGHPASS_FRACTION, ROBUST_ZOOMS

CONFIGS = {
    "paper": FastConfig(),
    "zoom+highpass": FastConfig(zooms=(1.15, 1.3), highpass_fraction=0.175),
    "robust": FastConfig(
        zooms=ROBUST_ZOOMS,
        highpass_fraction=ROBUST_HIGHPASS_FRACTION,
        baseline=True,
        **ROBUST_FAST,
    ),
}


def _wrong(sets: list[ImageSet], labels: list[str], config: LocalizerConfig) -> int:
    localizer = Localizer(config)
    node_of: dict[str, int] = {}
    wrong = 0
    for image_set, label in zip(sets, labels, strict=True):
        decision = localizer.localize(image_set)
        if label in node_of:
            wrong += not (decision.known and decision.node == node_of[label])
        else:
            wrong += decision.known
            node_of[label] = decision.node
    return wrong


def _thresholds(text: str) -> np.ndarray:
    start, stop, step = (float(v) for v in text.split(":"))
    return np.round(np.arange(start, stop + step / 2, step), 4)


def main() -> None:
    """Print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="folders of pipemap sim --save-sweeps")
    parser.add_argument("--thresholds", type=_thresholds, default="0.26:0.40:0.01")
    parser.add_argument("--only", choices=sorted(CONFIGS), default=None, help="one of them")
    args = parser.parse_args()
    runs = []
    for run in args.runs:
        folders = sorted(p for p in run.iterdir() if p.is_dir())
        runs.append((run.name, load_image_sets(folders), [read_info(f)["node"] for f in folders]))
    decisions = sum(len(sets) - 1 for _, sets, _ in runs)
    print(f"# wrong known/new decisions of {decisions} in {len(runs)} runs (first visits aside)")
    for name, fast in CONFIGS.items():
        if args.only and name != args.only:
            continue
        for t in args.thresholds:
            config = LocalizerConfig(threshold=float(t), active_vision=False, fast=fast)
            wrong = {run: _wrong(sets, labels, config) for run, sets, labels in runs}
            detail = " ".join(f"{run}:{n}" for run, n in wrong.items() if n)
            print(f"{name:<14} {t:.3f} {sum(wrong.values()):4d}  {detail}", flush=True)


if __name__ == "__main__":
    main()
