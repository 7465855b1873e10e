"""A log whose ``pipemap.run`` record is damaged: ``info`` says the settings are lost
(never a guessed ``explore right-hand``), and a replay refuses in one line rather
than replay with settings it would have to invent (the camera's lamp among them)."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from pipemap.recorder import METADATA_RUN
from tests.test_faults import STORED, assert_one_line, pipemap


@pytest.fixture(scope="module")
def damaged(tmp_path_factory: pytest.TempPathFactory) -> Path:
    data = bytearray(STORED.read_bytes())
    name = METADATA_RUN.encode()
    # A metadata record: opcode, u64 length, u32 name length, the name.
    at = data.find(struct.pack("<I", len(name)) + name) - 9
    assert data[at] == 0x0C
    (length,) = struct.unpack_from("<Q", data, at + 1)
    struct.pack_into("<Q", data, at + 1, length - 10)  # its map now runs past its end
    path = tmp_path_factory.mktemp("run") / "damaged_run.mcap"
    path.write_bytes(bytes(data))
    return path


def test_info_says_the_settings_are_lost(damaged: Path) -> None:
    done = pipemap("info", str(damaged))
    assert done.returncode == 1, done.stderr
    run = [line for line in done.stdout.splitlines() if line.startswith("run ")]
    assert run == ["run        lost: its pipemap.run record is damaged; the settings are not known"]
    assert "right-hand" not in done.stdout


@pytest.mark.parametrize("command", ["replay", "score"])
def test_a_replay_refuses_rather_than_invent_the_settings(command: str, damaged: Path) -> None:
    done = pipemap(command, str(damaged))
    assert_one_line(done, 2, "its pipemap.run record is damaged: the run's settings are lost")
