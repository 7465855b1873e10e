"""Open a pipemap log, look at its visits, replay it and score it: pipemap from Python.

Run it on any log (``pipemap record`` writes one); without an argument it uses the
stored regression log ``recordings/paper_autonomous.mcap`` of this repository::

    python examples/replay_and_score.py [LOG.mcap]
"""

from __future__ import annotations

import sys
from pathlib import Path

from pipemap import api
from pipemap.errors import PipemapError
from pipemap.localizer import PAPER

REPOSITORY = Path(__file__).resolve().parents[1]


def main(path: Path) -> None:
    log = api.open_log(path)
    meta = log.metadata
    print(
        f"{path.name}: network {meta['network']}, condition {meta['condition']}, "
        f"{log.integrity.value}"
    )

    # Every junction visit: when it ended, and what the camera saw.
    for sweep in log.visits():
        images = sweep.images
        print(
            f"  visit {sweep.visit_id}: {images.count} images of "
            f"{images.width}x{images.height} px at t = {sweep.end_ns / 1e9:.1f} s"
        )

    # The map, rebuilt from the robot's own sensors alone.
    result = api.replay(log)
    document = result.document()
    print(f"map: {len(document['nodes'])} junctions, {len(document['edges'])} pipes")

    # Scored against the simulator's truth, with pipemap's defaults and the paper's rule
    # (on a small 96 px log the paper's threshold alone merges look-alike junctions).
    for name, config in (("defaults", None), ("paper's rule", PAPER)):
        report = api.score(log, config)
        verdict = "correct" if report.map_correct else "wrong"
        print(f"score ({name}): map {verdict}, {report.counts()}")


if __name__ == "__main__":
    default = REPOSITORY / "recordings" / "paper_autonomous.mcap"
    try:
        main(Path(sys.argv[1]) if len(sys.argv) > 1 else default)
    except PipemapError as error:  # bad input: one line, no traceback
        sys.exit(f"error: {error}")
