"""``benchmarks/compare_hypotheses.py``: a log's online decisions against a replay with
one map. Run as a user runs it, on a stored log and on a copy with one decision changed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from pipemap.recorder import METADATA_RUN, LogWriter, Topic, read_log, schemas
from tests.conftest import REPO

SCRIPT = REPO / "benchmarks" / "compare_hypotheses.py"
STORED = REPO / "recordings" / "random8_loops.mcap"


def _compare(*logs: Path) -> list[str]:
    done = subprocess.run(
        [sys.executable, str(SCRIPT), *map(str, logs)],
        capture_output=True,
        text=True,
        check=False,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.splitlines()


def _with_decision_changed(path: Path, visit_id: int) -> None:
    """``STORED`` with visit ``visit_id``'s online decision naming another junction,
    deferred with two maps alive."""
    contents = read_log(STORED)
    with path.open("wb") as f, LogWriter(f, contents.metadata[METADATA_RUN]) as writer:
        for m in contents.messages:
            data = m.data
            if m.topic == Topic.DECISION:
                decision = schemas.Decision.FromString(data)
                if decision.visit_id == visit_id:
                    decision.node += 1
                    decision.hypotheses = 2
                    decision.deferred.append(decision.node - 1)
                    data = decision.SerializeToString()
            writer.write_serialized(m.topic, m.log_time_ns, data)


def test_it_finds_the_decisions_the_same_where_they_are_and_says_which_differs(
    tmp_path: Path,
) -> None:
    changed = tmp_path / "changed.mcap"
    _with_decision_changed(changed, 5)
    stored, other = _compare(STORED, changed)
    # The stored run branched nowhere: one map decides every visit as it was decided.
    assert stored.startswith(
        "random8_loops.mcap: 11 online decisions, 11 with one map, 11 the same (none differs); "
        "online with more than one map alive 0, deferred 0; one map: map correct, "
        "3 correct known, 8 correct new, 0 false merges, 0 false new"
    )
    assert other.startswith(
        "changed.mcap: 11 online decisions, 11 with one map, 10 the same "
        "(first differing: visit 5); online with more than one map alive 1, deferred 1; "
        "one map: map correct"
    )
