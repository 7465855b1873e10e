"""A batch run with real conditions (issue 20's keys ``obstacles``, ``tilt_deg``,
``lighting``): the settings reach the recording, and the blocked pipes its score
finds reach the results table as counts. One run at 32 px, in this process (the
task a Ray worker runs; tests/batch/test_batch_ray.py runs the engine itself)."""

from __future__ import annotations

import json
import math
from pathlib import Path

from pipemap.batch.results import result_row, write_run
from pipemap.batch.run import LOG_NAME, run_recording
from pipemap.batch.spec import parse_spec
from pipemap.recorder import METADATA_RUN, read_log

# The example of docs/stuck.md, at 32 px: two of its three deposits block their pipe.
SPEC = """\
[grid]
network = ["grid:2x3"]
seed = [1]
obstacles = [3]
tilt_deg = [2]
lighting = ["even"]
resolution = [32]
"""


def test_a_run_with_deposits_tilt_and_even_light_is_recorded_and_scored(tmp_path: Path) -> None:
    (point,) = parse_spec(SPEC).points
    outcome = run_recording([point], keep_log=True)
    assert outcome["record"]["run_ok"], outcome["record"]

    write_run(tmp_path, point, outcome, True, None)
    log = tmp_path / "runs" / point.run_id / LOG_NAME
    simulator = json.loads(read_log(log).metadata[METADATA_RUN]["simulator"])
    assert simulator["obstacles"]["count"] == 3
    assert simulator["camera"]["lamp_strength"] == 0.0
    assert math.isclose(simulator["explorer"]["tilt_rad"], math.radians(2.0))

    score = json.loads(outcome["runs"][point.run_id]["score_json"])
    blocked = score["blocked"]
    assert blocked["truly_blocked"] and blocked["marked"] == blocked["truly_blocked"]
    row = result_row(tmp_path, json.loads((log.parent / "result.json").read_text()))
    assert row["obstacles"] == 3 and row["tilt_deg"] == 2.0 and row["lighting"] == "even"
    for key in ("marked", "truly_blocked", "true_positives", "false_blocked", "missed"):
        assert row[f"blocked.{key}"] == len(blocked[key])
    assert row["map_correct"] is True
