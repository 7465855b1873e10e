"""``pipemap replay --save-log``: the replay's results as an MCAP log for Foxglove."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.reader import make_reader

from pipemap import api
from pipemap.cli import main
from pipemap.recorder.schemas import Decision

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


def test_the_results_log_holds_poses_the_map_and_the_decisions(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = RECORDINGS / "paper_autonomous.mcap"
    out = tmp_path / "results.mcap"
    assert main(["replay", str(log), "-o", str(tmp_path / "map.json"), "--save-log", str(out)]) == 0
    capsys.readouterr()
    with out.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        assert schemas == {
            "/replay/pose": "foxglove.PoseInFrame",
            "/tf": "foxglove.FrameTransform",
            "/replay/map": "foxglove.SceneUpdate",
            "/replay/decision": "pipemap.Decision",
        }
        messages = [(c.topic, m.log_time, m.data) for _, c, m in reader.iter_messages()]
    document = api.replay(log).document()
    nodes = [v["node"] for v in document["visits"]]
    poses = [PoseInFrame.FromString(d) for t, _, d in messages if t == "/replay/pose"]
    decisions = [Decision.FromString(d) for t, _, d in messages if t == "/replay/decision"]
    assert [d.node for d in decisions] == nodes
    assert len(poses) == len(nodes) == 13
    # A revisit is placed where the junction was first seen: the same point.
    first: dict[int, tuple[float, float]] = {}
    for node, pose in zip(nodes, poses, strict=True):
        at = (pose.pose.position.x, pose.pose.position.y)
        assert first.setdefault(node, at) == at
        assert pose.frame_id == "map"
    # Junctions 1.5 m apart on the paper's network: not all at one point.
    xs = sorted({p for p in first.values()})
    assert max(math.dist(xs[0], p) for p in xs) > 1.0
    last = SceneUpdate.FromString([d for t, _, d in messages if t == "/replay/map"][-1])
    ids = {e.id for e in last.entities}
    assert {f"node/{n}" for n in set(nodes)} <= ids
    assert sum(1 for i in ids if i.startswith("pipe/")) == len(document["edges"])


def test_save_log_is_checked_before_the_replay(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "results.mcap").write_bytes(b"earlier")
    status = main(
        [
            "replay",
            str(RECORDINGS / "paper_active.mcap"),
            "--save-log",
            str(tmp_path / "results.mcap"),
        ]
    )
    assert status == 2 and "refusing to overwrite" in capsys.readouterr().err
    assert (tmp_path / "results.mcap").read_bytes() == b"earlier"
