"""PackedLog: a log handed from one process to another as arrays and one byte string."""

from __future__ import annotations

import gc
import pickle
from pathlib import Path

import pytest

from pipemap.recorder import Integrity
from pipemap.recorder.reader import gc_paused
from pipemap.replay import FileSource, PackedLog

LOG = Path(__file__).resolve().parents[2] / "recordings" / "paper_autonomous.mcap"


def test_a_packed_log_unpacks_to_the_same_messages_topic_by_topic() -> None:
    source = FileSource(LOG)
    packed = pickle.loads(pickle.dumps(PackedLog.of(source, ("/robot/", "/truth/"))))
    again = packed.source()
    for prefix in ("/robot/", "/truth/"):
        original, copy = source.by_topic(prefix), again.by_topic(prefix)
        assert list(original) == list(copy)
        assert original == copy
        assert sum(len(ms) for ms in copy.values()) > 0
    assert again.run_metadata() == source.run_metadata()
    assert again.integrity is Integrity.OK
    assert again.name == str(LOG)


def test_packing_leaves_out_other_prefixes() -> None:
    source = FileSource(LOG)
    again = PackedLog.of(source, ("/robot/",)).source()
    assert again.by_topic("/truth/") == {}
    assert again.robot_messages() == source.robot_messages()


@pytest.mark.parametrize("enabled", [True, False])
def test_gc_paused_restores_the_collector(enabled: bool) -> None:
    was = gc.isenabled()
    try:
        (gc.enable if enabled else gc.disable)()
        with gc_paused():
            assert not gc.isenabled()
        assert gc.isenabled() is enabled
        with pytest.raises(RuntimeError), gc_paused():
            raise RuntimeError("boom")
        assert gc.isenabled() is enabled
    finally:
        (gc.enable if was else gc.disable)()
