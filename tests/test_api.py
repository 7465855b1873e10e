"""The Python API (``pipemap.api``): what a script or notebook does with pipemap."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipemap import api
from pipemap.errors import InputError, LogFormatError
from pipemap.localizer import PAPER, pairwise_matches, reference_match
from pipemap.recorder import RecordSettings

RECORDINGS = Path(__file__).resolve().parents[1] / "recordings"
LOG = RECORDINGS / "paper_autonomous.mcap"


@pytest.fixture(scope="module")
def log() -> api.Log:
    return api.open_log(LOG)


def test_a_log_tells_its_run_and_its_visits(log: api.Log) -> None:
    assert log.metadata["network"] == "paper"
    assert log.integrity is api.Integrity.OK and log.problem in (None, "")
    visits = log.visits()
    assert [v.visit_id for v in visits] == list(range(1, 14))
    assert all(v.images.count == 6 and v.images.width == 96 for v in visits)
    assert len(log.sweeps()) >= len(visits)
    assert [v.end_ns for v in visits] == sorted(v.end_ns for v in visits)


def test_replay_takes_a_log_or_a_path_and_gives_the_same_map(log: api.Log) -> None:
    by_log = api.replay(log).document()
    by_path = api.replay(str(LOG)).document()
    assert by_log == by_path
    assert len(by_log["nodes"]) == 7


def test_replay_drops_each_visits_images_unless_asked_to_keep_them(log: api.Log) -> None:
    """A long log's replay holds its map, not its images: by default no visit's sweep
    is kept; ``keep_images`` keeps each visit's, the images ``log.visits()`` gives."""
    dropped = api.replay(log)
    assert len(dropped.visit_sets) == 0
    assert len(dropped.visit_prepared) == len(dropped.visits) == 13  # for pair statistics
    kept = api.replay(log, keep_images=True)
    assert kept.document() == dropped.document()
    by_visit = {v.visit_id: v.images.images for v in log.visits()}
    for visit in kept.visits:
        assert (kept.visit_sets[visit.sweep_id].images == by_visit[visit.visit_id]).all()


def test_score_is_what_pipemap_score_stored(log: api.Log) -> None:
    stored = json.loads((RECORDINGS / "paper_autonomous.score.json").read_text())
    report = api.score(log)
    assert report.map_correct is stored["map_correct"] is True
    assert report.counts() == stored["decisions"]


def test_the_config_reaches_the_localizer(log: api.Log) -> None:
    """The paper's rule keeps no two-view fit: if the config were dropped, it would."""
    default = api.replay(log).document()["visits"]
    paper = api.replay(log, PAPER).document()["visits"]
    assert any(v["rotation_two_view_rad"] is not None for v in default)
    assert all(v["rotation_two_view_rad"] is None for v in paper)


def test_first_visits_have_no_similarity(log: api.Log) -> None:
    visits = api.replay(log).document()["visits"]
    assert [v["similarity"] for v in visits[:2]] == [None, None]
    assert all(v["similarity"] is not None for v in visits if v["candidate"] is not None)


def test_map_image_sets(paper_sets: dict[str, object]) -> None:
    shared = Path(__file__).resolve().parents[2] / "shared" / "paper_imagesets"
    doc = api.map_image_sets([shared / "1", shared / "4", shared / "2"])
    assert [v["known"] for v in doc["visits"]] == [False, False, True]
    assert doc["visits"][2]["node"] == doc["visits"][0]["node"]


def test_match_image_sets_is_every_pair_of_the_loaded_sets(
    paper_sets: dict[str, object], tmp_path: Path
) -> None:
    shared = Path(__file__).resolve().parents[2] / "shared" / "paper_imagesets"
    folders = [shared / "1", shared / "4", shared / "2_noise"]
    loaded = api.load_image_sets(folders)
    # Prepared as each folder is read, the very numbers of the sets loaded whole.
    assert api.match_image_sets(folders) == pairwise_matches(loaded)
    reference = api.match_image_sets(folders[:2], reference=True)
    assert reference == {(0, 1): reference_match(loaded[0], loaded[1])}
    # A set of another size is found while reading, before any pair.
    small = tmp_path / "small"
    small.mkdir()
    for j in range(1, 7):
        cv2.imwrite(str(small / f"camera_image{j}.png"), np.zeros((40, 40), np.uint8))
    with pytest.raises(InputError, match="6 images of 40x40, but"):
        api.match_image_sets([*folders, small])


def test_record_then_score(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    result = api.record(path, RecordSettings(network="paper", resolution_px=64, seed=3))
    assert result.ok and path.is_file()
    report = api.score(path)
    assert len(report.visits) == result.visits == len(api.open_log(path).visits())
    assert report.log == str(path)


def test_bad_input_raises_pipemap_errors(tmp_path: Path) -> None:
    with pytest.raises(LogFormatError, match="missing.mcap"):
        api.open_log(tmp_path / "missing.mcap")
    text = tmp_path / "notes.mcap"
    text.write_text("not a log")
    with pytest.raises(LogFormatError, match="notes.mcap"):
        api.open_log(text)
    with pytest.raises(InputError):
        api.map_image_sets([])
    # An existing file is never overwritten without asking, and nothing runs first.
    existing = tmp_path / "keep.mcap"
    existing.write_bytes(b"precious")
    with pytest.raises(InputError, match="exists"):
        api.record(existing, RecordSettings(network="paper", resolution_px=32))
    assert existing.read_bytes() == b"precious"
    with pytest.raises(InputError, match="does not exist"):
        api.record(tmp_path / "no" / "run.mcap", RecordSettings(network="paper"))


#: Names in the API's signatures that are not pipemap's own types.
_NOT_PIPEMAPS = {"Any", "Callable", "Path", "Sequence", "None"}


def test_the_api_exports_every_type_its_functions_take_and_give() -> None:
    import inspect
    import re

    named: set[str] = set()
    for name in api.__all__:
        value = getattr(api, name)
        if not inspect.isfunction(value):
            continue
        signature = inspect.signature(value)
        texts = [str(p.annotation) for p in signature.parameters.values()]
        texts.append(str(signature.return_annotation))
        for text in texts:
            named |= set(re.findall(r"\b[A-Z][A-Za-z]+\b", text)) - _NOT_PIPEMAPS
    assert {"RecordSettings", "RecordResult", "Progress", "MessageSource", "Log"} <= named
    for name in named:
        assert name in api.__all__, f"pipemap.api takes or gives {name} but does not export it"
    assert api.RecordSettings is RecordSettings
    assert api.RecordSettings(network="paper", explore=api.Explore.MAP).explore is api.Explore.MAP


def test_view_saves_the_replayed_log_as_a_rerun_recording(tmp_path: Path) -> None:
    target = tmp_path / "run.rrd"
    viewed = api.view(LOG, PAPER, save=target)
    assert target.stat().st_size > 0
    assert not viewed.contents.damage and not viewed.contents.truncated
    # The config reaches the replay: on this lamp-lit log the paper's rule merges
    # junctions that pipemap's defaults keep apart.
    paper = api.replay(LOG, PAPER).document()
    assert viewed.result.document() == paper != api.replay(LOG).document()


def test_view_refuses_a_save_that_is_not_an_rrd_before_reading_the_log(tmp_path: Path) -> None:
    with pytest.raises(InputError, match=r"\.rrd"):
        api.view(tmp_path / "missing.mcap", save=tmp_path / "run.png")
    assert list(tmp_path.iterdir()) == []
