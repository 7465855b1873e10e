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


def _points(collection: dict) -> dict[int, tuple[float, float]]:  # type: ignore[type-arg]
    return {
        f["properties"]["node"]: tuple(f["geometry"]["coordinates"])
        for f in collection["features"]
        if f["geometry"]["type"] == "Point"
    }


def test_a_map_document_is_placed_by_chaining_its_ports_and_pipe_lengths(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``pipemap export MAP.json --geojson``: the map document alone (no log, no
    replay); its junctions fall where the log's dead reckoning puts them, up to the
    turn of the frame and the error of taking driven lengths for straight pipes."""
    document_path = RECORDINGS / "paper_autonomous.map.json"
    document = json.loads(document_path.read_text())
    out = tmp_path / "map.geojson"
    assert main(["export", str(document_path), "--geojson", str(out)]) == 0
    assert "13 features" in capsys.readouterr().out
    collection = json.loads(out.read_text())
    assert "origin at junction 0" in collection["frame"]
    assert collection["unplaced"] == {"junctions": 0, "pipes": 0}
    points = _points(collection)
    assert points[0] == (0.0, 0.0)
    for node in document["nodes"]:
        feature = next(
            f for f in collection["features"] if f["properties"].get("node") == node["id"]
        )
        assert feature["properties"]["ports"] == len(node["ports"])
    # Each pipe that placed a junction is as long as the robot drove it.
    lengths = sorted(round(math.dist(points[e["u"]], points[e["v"]]), 6) for e in document["edges"])
    assert lengths == sorted(round(e["length_m"], 6) for e in document["edges"])

    # The log's own GeoJSON (dead reckoning at each exit scan), turned into the map's
    # frame by the best rotation about junction 0 (the robot's start, S).
    from_log = tmp_path / "log.geojson"
    assert (
        main(["export", str(RECORDINGS / "paper_autonomous.mcap"), "--geojson", str(from_log)]) == 0
    )
    logged = _points(json.loads(from_log.read_text()))
    assert logged.keys() == points.keys()
    turn = math.atan2(
        sum(lx * my - ly * mx for (lx, ly), (mx, my) in ((logged[k], points[k]) for k in points)),
        sum(lx * mx + ly * my for (lx, ly), (mx, my) in ((logged[k], points[k]) for k in points)),
    )
    c, s = math.cos(turn), math.sin(turn)
    errors = {
        k: math.dist((c * x - s * y, s * x + c * y), points[k]) for k, (x, y) in logged.items()
    }
    assert max(errors.values()) < 0.2, errors  # 0.125 m at most, at junction 2


@pytest.mark.parametrize(
    ("extra", "text", "expected"),
    [
        (["--tum", "{tmp}/tum"], None, "a map document gives --geojson only"),
        ([], "{not json", "not a JSON map document"),
        ([], '{"nodes": [{"id": 1}], "edges": [], "visits": []}', "malformed map"),
        ([], '{"nodes": [], "edges": [], "visits": []}', "the map has no junctions"),
    ],
)
def test_a_bad_map_document_is_one_line_and_exit_2(
    extra: list[str],
    text: str | None,
    expected: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    document = RECORDINGS / "paper_autonomous.map.json"
    if text is not None:
        document = tmp_path / "bad.json"
        document.write_text(text)
    out = tmp_path / "map.geojson"
    argv = ["export", str(document), "--geojson", str(out)]
    status = main([*argv, *(a.format(tmp=tmp_path) for a in extra)])
    stdout, stderr = capsys.readouterr()
    assert status == 2 and stdout == ""
    assert len(stderr.splitlines()) == 1 and expected in stderr, stderr
    assert not out.exists() and not (tmp_path / "tum").exists()
