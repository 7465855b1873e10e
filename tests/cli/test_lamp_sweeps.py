"""pipemap's own lamp-lit sweeps read right: ``sim --save-sweeps`` says in each
``sweep.txt`` how the sweep was lit, and ``match`` and ``map`` normalise lamp-lit
sets as a replay does (``--illumination`` overrides)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pipemap.errors import InputError
from pipemap.imagesets import RobotNotes, lamp_lit, read_robot_notes, write_image_set
from tests.cli.common import run

#: The paper's network from S at 200 px (the lamp on, the default): the first sweep
#: of each junction, and the return to S.
FIRST_OF = {"S": "0001", "A": "0002", "B": "0003", "C": "0005", "D": "0006"}


@pytest.fixture(scope="module")
def sweeps(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("lamp") / "sweeps"
    # Not through ``run``: a module fixture cannot take ``capfd``.
    from pipemap.cli import main

    assert (
        main(["sim", "--network", "paper", "--resolution", "200", "--save-sweeps", str(out)]) == 0
    )
    return out


def _similarity(argv: list[str], capfd: pytest.CaptureFixture[str]) -> float:
    status, out, err = run(["match", *argv, "--json"], capfd)
    assert status == 0, err
    (pair,) = json.loads(out)["pairs"]
    return float(pair["similarity"])


def test_saved_sweeps_say_they_were_lamp_lit(sweeps: Path) -> None:
    folders = sorted(p for p in sweeps.iterdir() if p.is_dir())
    assert len(folders) == 13
    assert {read_robot_notes(f).lighting for f in folders} == {"lamp"}
    assert lamp_lit(folders)


def test_match_normalises_lamp_lit_sweeps_unless_told_otherwise(
    sweeps: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    s, b = str(sweeps / FIRST_OF["S"]), str(sweeps / FIRST_OF["B"])
    auto = _similarity([s, b], capfd)
    lamp = _similarity([s, b, "--illumination", "lamp"], capfd)
    even = _similarity([s, b, "--illumination", "even"], capfd)
    assert auto == lamp
    # Unnormalised, the lamp's bright centre makes two different junctions alike.
    assert even > 0.6 and auto < 0.36


def test_map_without_the_two_view_check_finds_the_true_junctions(
    sweeps: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    folders = [str(p) for p in sorted(sweeps.iterdir()) if p.is_dir()]
    status, out, err = run(["map", *folders, "--no-two-view", "--json"], capfd)
    assert status == 0, err
    doc = json.loads(out)
    truth = [(Path(f) / "info.txt").read_text().split("node: ")[1].split()[0] for f in folders]
    predicted = [v["node"] for v in doc["visits"]]
    # The same partition: one predicted node per true junction, and back.
    assert len(set(zip(truth, predicted, strict=True))) == len(set(truth)) == len(set(predicted))
    status, out, err = run(["map", *folders, "--no-two-view", "--illumination", "even"], capfd)
    assert status == 0, err
    # Unnormalised, the lamp's bright centre makes different junctions alike and the map
    # merges them; only the robot's exit scans (sweep.txt) keep some apart.
    nodes = int(out.strip().splitlines()[-1].split(" nodes")[0])
    assert nodes < len(set(truth))


def test_lighting_round_trips_and_bad_values_are_named(tmp_path: Path) -> None:
    images = np.zeros((6, 8, 16), dtype=np.uint8)
    write_image_set(tmp_path / "a", images, {}, notes=RobotNotes(lighting="lamp"))
    write_image_set(tmp_path / "b", images, {}, notes=RobotNotes(lighting="even"))
    write_image_set(tmp_path / "c", images, {})
    assert read_robot_notes(tmp_path / "a").lighting == "lamp"
    assert read_robot_notes(tmp_path / "c").lighting is None
    assert lamp_lit([tmp_path / "a", tmp_path / "c"])
    assert not lamp_lit([tmp_path / "c"])
    with pytest.raises(InputError, match="--illumination"):
        lamp_lit([tmp_path / "a", tmp_path / "b"])
    (tmp_path / "c" / "sweep.txt").write_text("lighting: candle\n")
    with pytest.raises(InputError, match="lighting must be lamp or even"):
        read_robot_notes(tmp_path / "c")
