"""``pipemap map``: a sequence of junction visits as a map, as JSON and as a table,
and the rotation convention ``match`` and ``map`` share (docs/conventions.md).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pipemap.localizer import wrap_angle_rad
from tests.cli.common import make_set, run
from tests.conftest import PAPER_SETS, PaperSet


def map_set_triple(tmp_path: Path) -> list[str]:
    """A, B, then A again (a copy in its own folder): new, new, known."""
    a = make_set(tmp_path, "A", seed=1)
    b = make_set(tmp_path, "B", seed=2)
    again = make_set(tmp_path, "A2", seed=1)
    return [str(a), str(b), str(again)]


def test_map_json(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    dirs = map_set_triple(tmp_path)
    status, out, err = run(["map", *dirs, "--json"], capfd)
    assert status == 0, err
    assert err == ""
    doc = json.loads(out)
    # Image folders without the robot's exit scans: no ports.
    assert doc["nodes"] == [{"id": 0, "ports": []}, {"id": 1, "ports": []}]
    assert doc["edges"] == [
        {"u": 0, "u_port": None, "v": 1, "v_port": None, "label": 1, "length_m": None}
    ]
    visits = doc["visits"]
    assert [v["set"] for v in visits] == dirs
    assert [v["known"] for v in visits] == [False, False, True]
    assert [v["node"] for v in visits] == [0, 1, 0]
    assert visits[2]["candidate"] == 0
    assert visits[2]["similarity"] > 0.95
    assert visits[2]["image_shift"] == 0


def test_map_allow_repeat_lets_a_set_be_the_junction_before_it(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    a = make_set(tmp_path, "A", seed=1)
    again = make_set(tmp_path, "A2", seed=1)
    status, out, err = run(["map", str(a), str(again), "--json"], capfd)
    assert status == 0, err
    assert [v["node"] for v in json.loads(out)["visits"]] == [0, 1]  # a pipe joins two
    status, out, err = run(["map", str(a), str(again), "--json", "--allow-repeat"], capfd)
    assert status == 0, err
    doc = json.loads(out)
    assert [v["node"] for v in doc["visits"]] == [0, 0]  # the paper's rule: a self-loop
    assert [(e["u"], e["v"], e["label"]) for e in doc["edges"]] == [(0, 0, 1)]


def test_map_is_deterministic(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    dirs = map_set_triple(tmp_path)
    first = run(["map", *dirs, "--json"], capfd)
    second = run(["map", *dirs, "--json"], capfd)
    assert first[0] == second[0] == 0
    assert first[1] != ""
    assert first[1].encode() == second[1].encode()


def test_map_table(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    dirs = map_set_triple(tmp_path)
    status, out, err = run(["map", *dirs], capfd)
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].split() == ["set", "node", "known", "similarity", "margin", "rotation"]
    rows = [line.split() for line in lines[1:4]]
    assert [(row[0], row[1], row[2]) for row in rows] == [
        (dirs[0], "0", "no"),
        (dirs[1], "1", "no"),
        (dirs[2], "0", "yes"),
    ]
    # The rotation of the known visit, as --json reports it; none for new junctions.
    assert [row[5] for row in rows[:2]] == ["-", "-"]
    doc = json.loads(run(["map", *dirs, "--json"], capfd)[1])
    known = doc["visits"][2]
    rotation = known["rotation_two_view_rad"]
    rotation = known["rotation_rad"] if rotation is None else rotation
    assert float(rows[2][5]) == pytest.approx(rotation, abs=5e-5)
    assert lines[4:] == ["2 nodes; edges: 0-1 (1)"]


def test_one_rotation_convention(
    paper_sets: dict[str, PaperSet], capfd: pytest.CaptureFixture[str]
) -> None:
    """docs/conventions.md: a rotation of (A, B) is yaw_B - yaw_A. ``match A B`` names
    the pair in argument order; a map visit's pair is (this visit, its candidate)."""
    one, two, four = (str(PAPER_SETS / n) for n in ("1", "2", "4"))
    pairs = json.loads(run(["match", two, one, "--json"], capfd)[1])["pairs"]
    visit = json.loads(run(["map", one, four, two, "--json"], capfd)[1])["visits"][2]
    assert visit["candidate"] == 0 and visit["known"]
    assert visit["rotation_rad"] == pairs[0]["rotation_rad"]
    assert visit["rotation_pinhole_rad"] == pairs[0]["rotation_pinhole_rad"]
    # The other order turns the other way; the truth agrees on the sign.
    reverse = json.loads(run(["match", one, two, "--json"], capfd)[1])["pairs"][0]
    assert abs(reverse["rotation_rad"] + pairs[0]["rotation_rad"]) < 0.01
    # The recorded camera yaws (ground truth) agree on the sign and size.
    true_turn = wrap_angle_rad(paper_sets["1"].yaw_rad - paper_sets["2"].yaw_rad)
    assert abs(wrap_angle_rad(visit["rotation_two_view_rad"] - true_turn)) < 0.1


@pytest.mark.parametrize(
    ("flag", "other", "default"), [("--fov-deg", "60", "80"), ("--keep-top", "0.75", "0.5")]
)
def test_the_camera_flags_reach_the_map(
    flag: str, other: str, default: str, capfd: pytest.CaptureFixture[str]
) -> None:
    """The camera's field of view and kept part are the flags' values: the default's
    value given explicitly is the default's map, another value another map (a revisit's
    similarity and rotation move with them)."""
    dirs = [str(PAPER_SETS / n) for n in ("1", "2", "1_noise")]

    def mapped(*flags: str) -> dict[str, object]:
        status, out, err = run(["map", *dirs, "--json", *flags], capfd)
        assert status == 0, err
        doc: dict[str, object] = json.loads(out)
        return doc

    plain = mapped()
    assert mapped(flag, default) == plain
    changed = mapped(flag, other)
    assert changed != plain
    assert changed["visits"][2]["known"]  # type: ignore[index]
