"""Build a topological map from image-set folders (the paper's layout) in Python.

Each folder is one junction visit (``camera_image1..N``); the folders are taken in
order, as a robot would visit them. Without arguments it uses four of the paper's
own image sets from the team's ``shared/paper_imagesets`` beside this repository::

    python examples/map_image_sets.py [DIR ...]
"""

from __future__ import annotations

import sys
from pathlib import Path

from pipemap import api
from pipemap.errors import PipemapError

SHARED = Path(__file__).resolve().parents[2] / "shared" / "paper_imagesets"


def main(folders: list[Path]) -> None:
    document = api.map_image_sets(folders)
    for visit in document["visits"]:
        seen = f"known junction {visit['node']}" if visit["known"] else "new junction"
        similarity = visit["similarity"]
        best = "-" if similarity is None else f"{similarity:.3f}"
        print(f"{Path(visit['set']).name:>8}: {seen:<18} best similarity {best}")
    print(f"{len(document['nodes'])} junctions, {len(document['edges'])} pipes")


if __name__ == "__main__":
    given = [Path(arg) for arg in sys.argv[1:]]
    try:
        main(given or [SHARED / name for name in ("1", "4", "2", "10")])
    except PipemapError as error:  # bad input: one line, no traceback
        sys.exit(f"error: {error}")
