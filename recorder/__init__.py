"""The recorder: runs an episode with the localizer online and owns the log format.

A log is an MCAP file of protobuf messages (Foxglove's well-known schemas where one
fits, pipemap's own in ``schemas/pipemap_log.proto``); topics and metadata are
named in :mod:`recorder.topics`. :func:`record_run` writes a run, :func:`read_log`
reads one back: whole, up to where it was cut, or every chunk but the damaged ones;
:func:`iter_log` reads it as a stream, a message at a time, for a log too long to hold.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from pipemap.recorder.reader import (
    Damage,
    Integrity,
    LogChannel,
    LogContents,
    LogMessage,
    LogStream,
    iter_log,
    read_log,
)
from pipemap.recorder.topics import FORMAT_VERSION, METADATA_RESULT, METADATA_RUN, TOPICS, Topic

if TYPE_CHECKING:
    from pipemap.recorder.online import Explore, MapPolicy, OnlineLocalizer
    from pipemap.recorder.session import (
        Progress,
        RecordResult,
        RunObserver,
        record_run,
    )
    from pipemap.recorder.settings import RecordSettings
    from pipemap.recorder.writer import LogWriter

#: Loaded on first use (PEP 562): recording pulls in the simulator, which a command
#: that only reads logs should not pay for (0.1 s).
_LAZY = {
    "Explore": "pipemap.recorder.online",
    "MapPolicy": "pipemap.recorder.online",
    "OnlineLocalizer": "pipemap.recorder.online",
    "Progress": "pipemap.recorder.session",
    "RecordResult": "pipemap.recorder.session",
    "RecordSettings": "pipemap.recorder.settings",
    "RunObserver": "pipemap.recorder.session",
    "record_run": "pipemap.recorder.session",
    "LogWriter": "pipemap.recorder.writer",
}


def __getattr__(name: str) -> Any:
    if name not in _LAZY:
        raise AttributeError(f"module 'recorder' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(_LAZY[name]), name)
    globals()[name] = value
    return value


__all__ = [
    "FORMAT_VERSION",
    "METADATA_RESULT",
    "METADATA_RUN",
    "TOPICS",
    "Damage",
    "Explore",
    "Integrity",
    "LogChannel",
    "LogContents",
    "LogMessage",
    "LogStream",
    "LogWriter",
    "MapPolicy",
    "OnlineLocalizer",
    "Progress",
    "RecordResult",
    "RecordSettings",
    "RunObserver",
    "Topic",
    "iter_log",
    "read_log",
    "record_run",
]
