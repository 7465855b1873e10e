"""``pipemap map`` with the robot's notes: ports from ``sweep.txt``, and the port
check that ``--no-port-check`` turns off."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

from tests.conftest import PAPER_SETS

TEE = "3.141593,1.570796,-1.570796"  # behind, left, right


def _sets(tmp_path: Path, notes: dict[str, str]) -> list[str]:
    """Copies of shared sets with a ``sweep.txt`` of robot notes each."""
    folders = []
    for name, text in notes.items():
        target = tmp_path / name
        shutil.copytree(PAPER_SETS / name, target)
        (target / "sweep.txt").write_text(text, encoding="utf-8")
        folders.append(str(target))
    return folders


def _map(*args: str) -> dict[str, object]:
    done = subprocess.run(
        [sys.executable, "-m", "pipemap", "map", "--json", *args],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout)  # type: ignore[no-any-return]


def test_map_takes_ports_from_the_robot_notes_and_checks_a_revisit_by_them(
    tmp_path: Path,
) -> None:
    # 1 and 1_noise show the same junction (0.68 similar); the revisit's scan finds
    # two pipes where the junction has three: the exits contradict the images.
    folders = _sets(
        tmp_path,
        {
            "1": f"exits: {TEE}\ndeparture: 1.570796\n",
            "4": "exits: 3.141593\ndeparture: 3.141593\n",
            "1_noise": "exits: 3.141593,1.570796\n",
        },
    )
    checked = _map(*folders)
    assert [len(n["ports"]) for n in checked["nodes"]] == [3, 1, 2]  # type: ignore[index]
    visits = checked["visits"]
    assert visits[2]["known"] is False  # type: ignore[index]
    # Two exits can line up with three ports at no turn: junction 0 takes no place
    # among the two-view check's candidates, so it is neither fitted nor named.
    assert visits[2]["rejected"] == []  # type: ignore[index]
    assert checked["edges"][0] == {  # type: ignore[index]
        "u": 0,
        "u_port": 1,
        "v": 1,
        "v_port": 0,
        "label": 1,
        "length_m": None,
    }
    unchecked = _map("--no-port-check", *folders)
    assert unchecked["visits"][2]["known"] is True  # type: ignore[index]
    assert unchecked["visits"][2]["node"] == 0  # type: ignore[index]
    assert len(unchecked["nodes"]) == 2  # type: ignore[arg-type]
    # The paper's threshold rule takes the most similar junction first, and the
    # port check then names why it passed it over.
    paper = _map("--no-verify", *folders)
    assert paper["visits"][2]["known"] is False  # type: ignore[index]
    assert paper["visits"][2]["rejected"] == [  # type: ignore[index]
        {"candidate": 0, "reason": "2 exits where the junction has 3 ports"}
    ]
