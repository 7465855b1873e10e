"""``pipemap export RUN.mcap --geojson``: the replayed map for GIS tools."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from pipemap import api
from pipemap.cli import main
from pipemap.sim.network import build_network

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"


def test_junctions_are_points_where_the_robot_found_them_and_pipes_join_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = RECORDINGS / "paper_autonomous.mcap"
    out = tmp_path / "map.geojson"
    assert main(["export", str(log), "--geojson", str(out)]) == 0
    assert "13 features" in capsys.readouterr().out
    collection = json.loads(out.read_text())
    assert collection["type"] == "FeatureCollection"
    assert "local metric frame" in collection["frame"]
    assert collection["unplaced"] == {"junctions": 0, "pipes": 0}
    points = {
        f["properties"]["node"]: tuple(f["geometry"]["coordinates"])
        for f in collection["features"]
        if f["geometry"]["type"] == "Point"
    }
    lines = [f for f in collection["features"] if f["geometry"]["type"] == "LineString"]
    document = api.replay(log).document()
    assert len(points) == len(document["nodes"]) == 7
    assert len(lines) == len(document["edges"]) == 6
    for line, edge in zip(lines, document["edges"], strict=True):
        p = line["properties"]
        assert (p["from_node"], p["to_node"], p["length_m"]) == (
            edge["u"],
            edge["v"],
            edge["length_m"],
        )
        ends = [tuple(c) for c in line["geometry"]["coordinates"]]
        assert ends == [points[edge["u"]], points[edge["v"]]]
    # Placed by the dead reckoning, which starts at S in the network's own frame and
    # drifts by millimetres: each junction is within 5 cm of the node it truly is.
    report = api.score(log)
    network = build_network("paper")
    for visit in report.visits:
        true = network.node(visit.true_node)
        assert math.dist(points[visit.predicted_node], (true.x_m, true.y_m)) < 0.05


def test_a_log_without_exit_scans_has_no_places(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The placed run logs exit scans as placed but no dead reckoning: it says so."""
    log = RECORDINGS / "paper_active.mcap"
    assert main(["export", str(log), "--geojson", str(tmp_path / "map.geojson")]) == 0
    collection = json.loads((tmp_path / "map.geojson").read_text())
    assert collection["unplaced"]["junctions"] + len(
        [f for f in collection["features"] if f["geometry"]["type"] == "Point"]
    ) == len(api.replay(log).document()["nodes"])
