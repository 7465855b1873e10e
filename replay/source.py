"""Where a replay's messages come from: a log file read as the replay goes, a log
file read whole, or a list in memory (tests).

A source gives the ``/robot`` messages in the total order ``(log time, topic,
sequence)`` (:meth:`MessageSource.robot_messages`), or one at a time as its file is
read (:meth:`MessageSource.robot_stream`), plus the log's run metadata and
integrity. The ``/truth`` messages are read only for scoring, by
:meth:`MessageSource.truth`.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable, Collection, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from pipemap.errors import LogFormatError
from pipemap.recorder import (
    METADATA_RUN,
    Integrity,
    LogContents,
    LogMessage,
    LogStream,
    Topic,
    iter_log,
    read_log,
)
from pipemap.recorder.topics import ROBOT_PREFIX

__all__ = [
    "FileSource",
    "MemorySource",
    "MessageSource",
    "REQUIRED_TOPICS",
    "StreamSource",
    "ordered",
]

#: A replay needs the camera: its images and the sweep commands that frame them.
REQUIRED_TOPICS = (Topic.SWEEP, Topic.IMAGE)


def ordered(messages: Sequence[LogMessage]) -> list[LogMessage]:
    """The total order of replay: log time, then topic, then sequence."""
    return sorted(messages, key=lambda m: (m.log_time_ns, m.topic, m.sequence))


class MessageSource(Protocol):
    """What a replay reads."""

    @property
    def name(self) -> str:
        """A label for messages to the user (the file's path)."""
        ...

    def robot_messages(self) -> list[LogMessage]:
        """Every ``/robot`` message, in the total order."""
        ...

    def robot_stream(self) -> Iterator[LogMessage]:
        """The ``/robot`` messages one at a time: in the total order, or as a file is
        read (in file order, which a replay puts in the total order itself). Once it
        is exhausted the integrity, duration, metadata and truth are final."""
        ...

    def run_metadata(self) -> dict[str, str]:
        """The ``pipemap.run`` metadata record."""
        ...

    @property
    def integrity(self) -> Integrity:
        """Whether the log was read whole."""
        ...

    def truth(self) -> list[LogMessage]:
        """Every ``/truth`` message, in the total order (for scoring only)."""
        ...

    @property
    def duration_ns(self) -> int:
        """Log time from the first message to the last (of every topic a file holds,
        of the ``/robot`` ones in memory)."""
        ...

    def by_topic(self, prefix: str) -> dict[str, list[LogMessage]]:
        """The messages of every topic under ``prefix``, by topic, in file order
        (for viewing, which orders each topic by time itself)."""
        ...

    def every_message(self) -> Iterator[LogMessage]:
        """Every message the source keeps, one at a time in file order (a view's
        pass: a file read as it goes is not held)."""
        ...


@dataclass
class MemorySource:
    """Messages held in memory."""

    messages: list[LogMessage]
    metadata: dict[str, str]
    name: str = "<memory>"
    integrity: Integrity = Integrity.OK

    def robot_messages(self) -> list[LogMessage]:
        return ordered([m for m in self.messages if m.topic.startswith(ROBOT_PREFIX)])

    def robot_stream(self) -> Iterator[LogMessage]:
        return iter(self.robot_messages())

    def run_metadata(self) -> dict[str, str]:
        return dict(self.metadata)

    def truth(self) -> list[LogMessage]:
        return ordered([m for m in self.messages if m.topic.startswith("/truth/")])

    def by_topic(self, prefix: str) -> dict[str, list[LogMessage]]:
        return _grouped(m for m in self.messages if m.topic.startswith(prefix))

    def every_message(self) -> Iterator[LogMessage]:
        return iter(self.messages)

    @property
    def duration_ns(self) -> int:
        times = [m.log_time_ns for m in self.messages if m.topic.startswith(ROBOT_PREFIX)]
        return max(times) - min(times) if times else 0


class _LogFile:
    """What a source read from a file says of it (``_contents``: the log as read)."""

    path: Path
    _contents: LogContents

    @property
    def name(self) -> str:
        return str(self.path)

    @property
    def integrity(self) -> Integrity:
        return self._contents.integrity

    @property
    def duration_ns(self) -> int:
        return self._contents.duration_ns

    @property
    def problem(self) -> str:
        """What is wrong with the file, when its integrity is not ``ok``."""
        return self._contents.problem

    @property
    def contents(self) -> LogContents:
        """The log as read (so far, while a :class:`StreamSource` reads it): channels,
        counts, metadata, damage; the messages a :class:`FileSource` keeps."""
        return self._contents

    def run_metadata(self) -> dict[str, str]:
        # Absent only where its record was damaged (the reader accepts that log).
        return dict(self._contents.metadata.get(METADATA_RUN, {}))


class FileSource(_LogFile):
    """A log file, read once; the truth is kept apart and handed out only on request.

    ``topics``, if given, are the only ``/robot`` and ``/truth`` topics kept: a replay
    reads four of the log's topics, and the others (the IMU, wheels, ranges,
    controller and true poses: nine messages in ten) need not be held. The counts,
    times and integrity still cover the whole log."""

    def __init__(self, path: Path | str, topics: Collection[str] | None = None) -> None:
        self.path = Path(path)
        self._contents = read_log(self.path, keep=_keeper(topics))
        _check_one_run(self.path, self._contents)
        _check_camera(self.path, self._contents)
        # Grouped by topic in one pass (a view wants the topics apart, a replay the
        # /robot ones together), and put in order once: a replay and a view both ask.
        self._topics = _grouped(self._contents.messages)
        self._robot: list[LogMessage] | None = None
        self._truth: list[LogMessage] | None = None

    def robot_messages(self) -> list[LogMessage]:
        if self._robot is None:
            self._robot = ordered(_joined(self.by_topic(ROBOT_PREFIX)))
        return list(self._robot)

    def robot_stream(self) -> Iterator[LogMessage]:
        return iter(self.robot_messages())

    def truth(self) -> list[LogMessage]:
        if self._truth is None:
            self._truth = ordered(_joined(self.by_topic("/truth/")))
        return list(self._truth)

    def by_topic(self, prefix: str) -> dict[str, list[LogMessage]]:
        return {t: list(ms) for t, ms in self._topics.items() if t.startswith(prefix)}

    def every_message(self) -> Iterator[LogMessage]:
        return iter(self._contents.messages)


class StreamSource(_LogFile):
    """A log file read as a replay goes: each message is handed out once and not
    kept, so a replay of it (:func:`replay.replayer.replay`) holds the map and the
    visit at hand, not the log. The ``/truth`` messages among ``topics`` are few
    (one a sweep, and the network) and are kept for scoring.

    The file is opened here: a missing, empty or foreign file is refused at once.
    Its counts, times, damage and integrity are final once a pass has read it to its
    end; its run metadata, which opens every pipemap log, is known from the first
    message. Another pass (:meth:`robot_messages`, :meth:`by_topic`, or a replay
    that must start again) reads the file again."""

    def __init__(self, path: Path | str, topics: Collection[str] | None = None) -> None:
        self.path = Path(path)
        self._keep = _keeper(topics)
        self._next: LogStream | None = iter_log(self.path, self._keep)
        self._contents = self._next.contents
        _check_one_run(self.path, self._contents)
        self._truth: list[LogMessage] | None = None
        self._read = False  # whether a pass has read the whole file

    def _pass(self) -> Iterator[LogMessage]:
        """Every kept message, in file order, once; the truth is kept on the way."""
        stream, self._next = self._next or iter_log(self.path, self._keep), None
        self._contents = stream.contents
        truth: list[LogMessage] = []
        with stream:
            for m in stream:
                if m.topic.startswith("/truth/"):
                    truth.append(m)
                yield m
        self._truth, self._read = truth, True
        _check_one_run(self.path, self._contents)
        _check_camera(self.path, self._contents)

    def robot_stream(self) -> Iterator[LogMessage]:
        return (m for m in self._pass() if m.topic.startswith(ROBOT_PREFIX))

    def robot_messages(self) -> list[LogMessage]:
        return ordered(list(self.robot_stream()))

    def truth(self) -> list[LogMessage]:
        if self._truth is None:
            for _ in self._pass():
                pass
        return ordered(self._truth or [])

    def by_topic(self, prefix: str) -> dict[str, list[LogMessage]]:
        return _grouped(m for m in self._pass() if m.topic.startswith(prefix))

    def every_message(self) -> Iterator[LogMessage]:
        """Every kept message, one at a time in file order, none kept (afterwards
        the counts, damage and integrity are final)."""
        return self._pass()


def _keeper(topics: Collection[str] | None) -> Callable[[str], bool]:
    """Which topics a file source keeps: ``topics``, or every ``/robot`` and
    ``/truth`` one."""
    if topics is None:
        return lambda topic: topic.startswith((ROBOT_PREFIX, "/truth/"))
    wanted = frozenset(topics)
    return lambda topic: topic in wanted


def _check_one_run(path: Path, contents: LogContents) -> None:
    """Refuse a file of several runs (merged or joined by another program): a map or a
    score is of one run, and the file does not say which one is meant."""
    if contents.several_runs:
        raise LogFormatError(f"{path}: {contents.several_runs}")


def _check_camera(path: Path, contents: LogContents) -> None:
    """Refuse a whole log without the camera's channels; a log cut short or damaged
    before them simply holds no sweep (an empty map)."""
    topics = {c.topic for c in contents.channels.values()}
    missing = [t for t in REQUIRED_TOPICS if t not in topics]
    if missing and contents.integrity is Integrity.OK:
        raise LogFormatError(f"{path}: no {', '.join(missing)} channel in this log")


def _grouped(messages: Iterable[LogMessage]) -> dict[str, list[LogMessage]]:
    topics: defaultdict[str, list[LogMessage]] = defaultdict(list)
    for m in messages:
        topics[m.topic].append(m)
    return dict(topics)


def _joined(topics: dict[str, list[LogMessage]]) -> list[LogMessage]:
    return [m for messages in topics.values() for m in messages]
