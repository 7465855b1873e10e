"""A replay decides each visit as soon as the log has told all of it, drops what it
no longer needs, and gives the very map of deciding after reading the whole log,
also where the log's order or numbering makes it start again and read it whole."""

from __future__ import annotations

import gc
import io
import os
import shutil
import weakref
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from pipemap import recorder
from pipemap.cli.app import main
from pipemap.cli.replay_commands import progress_printer
from pipemap.errors import LogFormatError
from pipemap.localizer import LocalizerConfig, dumps_document
from pipemap.localizer import localizer as localizer_module
from pipemap.recorder import METADATA_RESULT, METADATA_RUN, LogMessage, LogWriter, Topic, read_log
from pipemap.recorder.schemas import NodeEvent, SweepCommand
from pipemap.replay import (
    REPLAY_TOPICS,
    SCORE_TOPICS,
    FileSource,
    MemorySource,
    ReplayResult,
    StreamSource,
    replay,
    score_replay,
)
from pipemap.replay import replayer as replayer_module
from pipemap.replay.info import log_info as info_document

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"
ACTIVE = RECORDINGS / "paper_active.mcap"  # has probe sweeps
AUTONOMOUS = RECORDINGS / "paper_autonomous.mcap"


class _Counted:
    """A source whose robot messages are counted as the replay takes them."""

    def __init__(self, source: MemorySource) -> None:
        self.source = source
        self.taken = 0

    def __getattr__(self, name: str) -> object:
        return getattr(self.source, name)

    def robot_stream(self) -> Iterator[LogMessage]:
        for m in self.source.robot_stream():
            self.taken += 1
            yield m


def _memory(path: Path, messages: list[LogMessage] | None = None) -> MemorySource:
    """The log at ``path`` as a source in memory (its robot messages replaced by
    ``messages``, in that order, if given)."""
    file = FileSource(path)
    robot = file.robot_messages() if messages is None else messages
    return _Listed(robot + file.truth(), file.run_metadata(), str(path))


class _Listed(MemorySource):
    """A source in memory that hands its robot messages out in the order it holds
    them, not sorted (as a file read as it goes does)."""

    def robot_stream(self) -> Iterator[LogMessage]:
        return iter([m for m in self.messages if m.topic.startswith("/robot/")])


def _whole(source: MemorySource) -> ReplayResult:
    """The replay that decides every visit after reading the whole log."""
    return replayer_module._Replay(source, LocalizerConfig(), None, True, whole=True).run()


def _visit_of(m: LogMessage) -> int | None:
    """The visit a sweep's start command or a node event names."""
    if m.topic == Topic.SWEEP:
        command = SweepCommand.FromString(m.data)
        return int(command.visit_id) if command.phase == SweepCommand.START else None
    if m.topic == Topic.NODE:
        return int(NodeEvent.FromString(m.data).visit_id)
    return None


@pytest.fixture
def runs(monkeypatch: pytest.MonkeyPatch) -> list[bool]:
    """Whether each replay run was the whole-log one, in order."""
    seen: list[bool] = []
    real = replayer_module._Replay.run

    def run(self: replayer_module._Replay) -> ReplayResult:
        seen.append(self.whole)
        return real(self)

    monkeypatch.setattr(replayer_module._Replay, "run", run)
    return seen


def _same(a: ReplayResult, b: ReplayResult) -> None:
    assert dumps_document(a.document()) == dumps_document(b.document())
    assert a.warnings == b.warnings and a.breaks == b.breaks
    assert (a.sweeps, a.images) == (b.sweeps, b.images)


@pytest.mark.parametrize("path", [ACTIVE, AUTONOMOUS], ids=["active", "autonomous"])
def test_each_visit_is_decided_as_soon_as_the_log_has_told_it(
    path: Path, monkeypatch: pytest.MonkeyPatch, runs: list[bool]
) -> None:
    source = _Counted(_memory(path))
    total = len(source.source.robot_messages())
    taken_at: list[int] = []
    real = localizer_module.Localizer.localize

    def localize(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        taken_at.append(source.taken)
        return real(self, *args, **kwargs)

    monkeypatch.setattr(localizer_module.Localizer, "localize", localize)
    result = replay(source)  # type: ignore[arg-type]
    assert runs == [False]
    assert len(taken_at) == len(result.visits) == 13
    # Each visit but the last is decided before the log's end, the first in its first
    # tenth: read as it goes, the replay never holds the whole log.
    assert taken_at[0] < total / 10
    assert all(a < b for a, b in zip(taken_at, taken_at[1:], strict=False))
    assert taken_at[-2] < total
    monkeypatch.setattr(localizer_module.Localizer, "localize", real)
    _same(result, _whole(_memory(path)))


def _alive_at_decisions(monkeypatch: pytest.MonkeyPatch, keep_sets: bool) -> list[int]:
    """How many of the replay's sweeps are alive at each decision of a replay of
    ``paper_active`` (which holds probe sweeps)."""
    made: list[weakref.ref[object]] = []
    alive: list[int] = []
    real_ended = replayer_module.SweepAssembler._ended
    real_localize = localizer_module.Localizer.localize

    def ended(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        sweep = real_ended(self, *args, **kwargs)
        if sweep is not None:
            made.append(weakref.ref(sweep))
        return sweep

    def localize(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        gc.collect()
        alive.append(sum(r() is not None for r in made))
        return real_localize(self, *args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(replayer_module.SweepAssembler, "_ended", ended)
        patch.setattr(localizer_module.Localizer, "localize", localize)
        result = replay(_memory(ACTIVE), keep_sets=keep_sets)
    assert len(result.visit_sets) == (13 if keep_sets else 0)
    return alive


def test_a_replay_without_sets_drops_each_sweep_once_decided(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Without the sets, a decision holds its own visit's sweeps (the sweep and its
    # probes, two at most here) and nothing of the visits before.
    assert max(_alive_at_decisions(monkeypatch, keep_sets=False)) <= 3
    assert _alive_at_decisions(monkeypatch, keep_sets=True)[-1] >= 13


def test_a_log_time_that_goes_back_is_replayed_whole_to_the_same_map(runs: list[bool]) -> None:
    messages = FileSource(AUTONOMOUS).robot_messages()
    # The last message first: the next one's log time then goes back.
    shuffled = [messages[-1], *messages[:-1]]
    result = replay(_memory(AUTONOMOUS, shuffled))
    assert runs == [False, True]
    _same(result, replay(_memory(AUTONOMOUS)))


def test_a_visit_told_after_a_later_one_is_replayed_whole_to_the_same_map(
    runs: list[bool],
) -> None:
    messages = FileSource(ACTIVE).robot_messages()
    # Visit 2's departure told only just before visit 4 begins, in log time too: the
    # order is kept, only the visit numbering tells that visit 2 was not over.
    departure = next(
        i
        for i, m in enumerate(messages)
        if m.topic == Topic.NODE
        and NodeEvent.FromString(m.data).kind == NodeEvent.DEPARTURE
        and NodeEvent.FromString(m.data).visit_id == 2
    )
    fourth = messages[next(i for i, m in enumerate(messages) if _visit_of(m) == 4)].log_time_ns
    later = next(i for i, m in enumerate(messages) if m.log_time_ns == fourth)
    late = messages[departure]._replace(log_time_ns=fourth)
    moved = [*messages[:departure], *messages[departure + 1 : later], late, *messages[later:]]
    result = replay(_memory(ACTIVE, moved))
    assert runs == [False, True]
    _same(result, _whole(_memory(ACTIVE, moved)))
    # The whole-log replay gives visit 2 its departure wherever the log tells it.
    _same(result, replay(_memory(ACTIVE)))


def test_a_lost_visit_found_only_later_still_breaks_the_path_there(runs: list[bool]) -> None:
    """A visit missing without a trace (none of its messages in the log) is a jump in
    the visit numbers; a sweep skipped later makes the log lossy, and the path must
    then break at the jump, as the whole-log replay breaks it."""
    messages = FileSource(AUTONOMOUS).robot_messages()
    first = next(i for i, m in enumerate(messages) if _visit_of(m) == 4)
    fifth = messages[next(i for i, m in enumerate(messages) if _visit_of(m) == 5)].log_time_ns
    # Visit 5 from its first log time on (its first image has its start's log time).
    after = next(i for i, m in enumerate(messages) if m.log_time_ns >= fifth)
    kept = messages[:first] + messages[after:]
    # An image of a later sweep goes missing: that sweep is skipped, with a warning.
    starts = [i for i, m in enumerate(kept) if m.topic == Topic.SWEEP and _visit_of(m) == 9]
    image = next(i for i in range(starts[0], len(kept)) if kept[i].topic == Topic.IMAGE)
    kept = kept[:image] + kept[image + 1 :]
    result = replay(_memory(AUTONOMOUS, kept))
    assert runs[-2:] == [False, True]
    assert result.breaks, "the jump from visit 3 to 5 breaks the path"
    assert [w for w in result.warnings if "skipped" in w] == [
        f"{AUTONOMOUS}: sweep 14 of visit 9 skipped: image 2 of 6 (284.869 s) is missing"
    ]
    _same(result, _whole(_memory(AUTONOMOUS, kept)))


def test_progress_counts_visits_and_gives_the_total_once_the_log_is_read() -> None:
    calls: list[tuple[int, int | None]] = []
    replay(_memory(ACTIVE), progress=lambda done, total: calls.append((done, total)))
    assert [done for done, _ in calls] == list(range(1, 14))
    # Visit 13, the last, is decided after the log's end: only then is the total known.
    assert calls[:-1] == [(done, None) for done in range(1, 13)]
    assert calls[-1] == (13, 13)


def test_the_progress_line_shows_the_total_when_known() -> None:
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    err = Terminal()
    show = progress_printer(err)
    show(1, None)
    show(2, 2)
    assert err.getvalue() == "\rreplaying: 1 visits \rreplaying: 2/2 visits \n"


def test_a_file_read_as_it_goes_is_decided_on_long_before_its_end(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    source = StreamSource(AUTONOMOUS, REPLAY_TOPICS)
    read_at: list[int] = []
    real = localizer_module.Localizer.localize

    def localize(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        read_at.append(sum(source.contents.counts.values()))
        return real(self, *args, **kwargs)

    monkeypatch.setattr(localizer_module.Localizer, "localize", localize)
    result = replay(source, keep_sets=False)
    total = sum(source.contents.counts.values())
    assert total == sum(FileSource(AUTONOMOUS).contents.counts.values())
    # The first visit is decided with a fifth of the file read, and every visit but
    # the last before the end: the source keeps no message, so nothing holds the log.
    assert read_at[0] < total / 5 and read_at[-2] < total
    monkeypatch.setattr(localizer_module.Localizer, "localize", real)
    _same(result, replay(FileSource(AUTONOMOUS, REPLAY_TOPICS), keep_sets=False))


@pytest.mark.parametrize("path", sorted(RECORDINGS.glob("*.mcap")), ids=lambda p: p.stem)
def test_a_file_read_as_it_goes_scores_as_a_file_read_whole(path: Path) -> None:
    streamed, whole = StreamSource(path, SCORE_TOPICS), FileSource(path, SCORE_TOPICS)
    a, b = replay(streamed), replay(whole)
    _same(a, b)
    assert streamed.integrity is whole.integrity and streamed.duration_ns == whole.duration_ns
    threshold = LocalizerConfig().threshold
    scored = score_replay(a, streamed, threshold).json_text(with_latency=False)
    assert scored == score_replay(b, whole, threshold).json_text(with_latency=False)


def test_a_file_read_as_it_goes_is_refused_before_any_work(tmp_path: Path) -> None:
    with pytest.raises(LogFormatError, match="no such file"):
        StreamSource(tmp_path / "missing.mcap")
    (tmp_path / "empty.mcap").write_bytes(b"")
    with pytest.raises(LogFormatError, match="empty.mcap"):
        StreamSource(tmp_path / "empty.mcap")


@pytest.fixture(scope="module")
def out_of_order(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``paper_autonomous`` written again with its last camera message first: its log
    time goes back as the file is read (MCAP allows any order)."""
    contents = read_log(AUTONOMOUS)
    camera = [i for i, m in enumerate(contents.messages) if m.topic == Topic.SWEEP]
    last = contents.messages[camera[-1]]
    rest = [m for i, m in enumerate(contents.messages) if i != camera[-1]]
    path = tmp_path_factory.mktemp("order") / "out_of_order.mcap"
    with path.open("wb") as f, LogWriter(f, contents.metadata[METADATA_RUN]) as writer:
        for m in [last, *rest]:
            writer.write_serialized(m.topic, m.log_time_ns, m.data)
        writer.finish(contents.metadata[METADATA_RESULT])
    return path


def test_a_file_whose_log_time_goes_back_replays_to_the_same_map(
    out_of_order: Path, runs: list[bool]
) -> None:
    result = replay(StreamSource(out_of_order, REPLAY_TOPICS), keep_sets=False)
    assert runs == [False, True]
    plain = replay(StreamSource(AUTONOMOUS, REPLAY_TOPICS), keep_sets=False)
    assert dumps_document(result.document()) == dumps_document(plain.document())


def test_info_counts_the_sweeps_of_a_file_whose_log_time_goes_back(out_of_order: Path) -> None:
    mixed, plain = info_document(out_of_order), info_document(AUTONOMOUS)
    assert mixed["sweeps"] == plain["sweeps"] == 18  # 13 visits, 5 probe sweeps
    assert mixed["messages"] == plain["messages"] and mixed["visits"] == plain["visits"]
    assert mixed["integrity"] == "ok"


def _cut_while_read(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Every StreamSource of ``path`` cuts the file to a third as it hands out its
    100th robot message (another program truncating it while it is read)."""
    real = StreamSource.robot_stream

    def robot_stream(self: StreamSource) -> Iterator[LogMessage]:
        for i, m in enumerate(real(self)):
            if i == 100 and self.path == path:
                os.truncate(path, path.stat().st_size // 3)
            yield m

    monkeypatch.setattr(StreamSource, "robot_stream", robot_stream)


def test_a_file_cut_while_it_is_replayed_is_refused_in_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "cut.mcap"
    shutil.copyfile(AUTONOMOUS, path)
    _cut_while_read(path, monkeypatch)
    with pytest.raises(LogFormatError, match="cut shorter while it was being read"):
        replay(StreamSource(path, REPLAY_TOPICS))
    target = tmp_path / "map.json"
    for command in (["replay", str(path), "-o", str(target)], ["score", str(path), "--json"]):
        shutil.copyfile(AUTONOMOUS, path)
        capsys.readouterr()
        assert main(command) == 2
        out, err = capsys.readouterr()
        assert err.count("\n") == 1 and "cut shorter while it was being read" in err
        assert "Traceback" not in err and out == "" and not target.exists()


def test_info_on_a_file_cut_while_it_is_read_is_refused_in_one_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "cut.mcap"
    shutil.copyfile(AUTONOMOUS, path)
    real = recorder.iter_log

    def iter_log(*args: Any, **kwargs: Any) -> Iterator[LogMessage]:
        stream = real(*args, **kwargs)

        class Cutting:  # the stream, the file cut as its 1000th message is handed out
            contents = stream.contents

            def __enter__(self) -> Cutting:
                return self

            def __exit__(self, *exc: object) -> None:
                stream.close()

            def close(self) -> None:
                stream.close()

            def __iter__(self) -> Iterator[LogMessage]:
                for i, m in enumerate(stream):
                    if i == 1000:
                        os.truncate(path, path.stat().st_size // 3)
                    yield m

        return Cutting()  # type: ignore[return-value]

    monkeypatch.setattr(recorder, "iter_log", iter_log)
    assert main(["info", str(path)]) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and "cut shorter while it was being read" in err
    assert "Traceback" not in err and out == ""
