"""Named settings of the localizer: the paper's threshold and pipemap's ``--robust``.

Plain numbers, importable without numpy or OpenCV, so that the command line can
show them in its help at no cost. Each is defined here once; everything that
needs one (the localizer's defaults, the CLI's presets, the experiments, the
tests) imports it from here.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "PAPER_THRESHOLD",
    "ROBUST_FAST",
    "ROBUST_HIGHPASS_FRACTION",
    "ROBUST_THRESHOLD",
    "ROBUST_ZOOMS",
]

#: The paper's known/new threshold on image-set similarity (Li et al. 2023).
PAPER_THRESHOLD = 0.36

#: ``--robust``: pipemap's similarity for cameras off the junction centre. Zoom
#: factors searched, the high-pass sigma as a fraction of the image width, and the
#: threshold on the similarity above the pair's baseline that goes with them
#: (measured with ``benchmarks/eval_similarity.py``; see docs).
ROBUST_ZOOMS = (1.15, 1.3)
ROBUST_HIGHPASS_FRACTION = 0.125
ROBUST_THRESHOLD = 0.062
#: What ``--robust`` keeps of the fast path's refinement it was tuned with (before the
#: fast path took the paper's quarter scale and every offset): plain decimation, two
#: offsets. Keyword arguments of :class:`pipemap.localizer.FastConfig`.
ROBUST_FAST: dict[str, Any] = {"paper_resampling": False, "refine_offsets": 2}
