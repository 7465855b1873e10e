"""Truth that cannot be read is named per topic, and the rest is still scored: a
``/truth/network`` that does not decode or holds no node, ``/truth/sweep`` messages
that do not decode.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pipemap.recorder import Topic, read_log, schemas
from tests.test_faults import STORED, pipemap, rewrite

#: Bytes that are not a protobuf message: a length that runs past the end.
UNDECODABLE = b"\x0a\xff\xff\xff\x0f"


@pytest.mark.parametrize(
    ("payload", "said"),
    [
        (UNDECODABLE, "does not decode"),
        (schemas.SceneUpdate().SerializeToString(), "holds no node"),
    ],
    ids=["undecodable", "empty"],
)
def test_an_unusable_true_network_is_said_and_the_rest_is_scored(
    payload: bytes, said: str, tmp_path: Path
) -> None:
    broken = tmp_path / "network.mcap"
    rewrite(STORED, broken, lambda _i, m: payload if m.topic == Topic.NETWORK else None)
    done = pipemap("score", "--json", str(broken))
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    assert (
        f"pipemap: warning: {broken}: /truth/network {said}: coverage, ports and blocked "
        "pipes are not scored"
    ) in done.stderr.splitlines()
    doc = json.loads(done.stdout)
    assert doc["coverage"] is None
    # Every decision still scored against /truth/sweep.
    assert doc["visits"] == 13 and sum(doc["decisions"].values()) == 13


def test_true_sweeps_that_do_not_decode_are_counted_and_the_rest_scored(tmp_path: Path) -> None:
    sweeps = [i for i, m in enumerate(read_log(STORED).messages) if m.topic == Topic.TRUE_SWEEP]
    lost = {sweeps[0], sweeps[3]}
    broken = tmp_path / "sweeps.mcap"
    rewrite(STORED, broken, lambda i, _m: UNDECODABLE if i in lost else None)
    done = pipemap("score", "--json", str(broken))
    assert done.returncode == 0, done.stderr
    assert (
        f"pipemap: warning: {broken}: 2 /truth/sweep message(s) do not decode: their sweeps' "
        "truth is lost"
    ) in done.stderr.splitlines()
    assert json.loads(done.stdout)["coverage"] is not None
