"""The recorder: runs an episode with the localizer online and owns the log format.

A log is an MCAP file of protobuf messages (Foxglove's well-known schemas where one
fits, pipemap's own in ``schemas/pipemap_log.proto``); topics and metadata are
named in :mod:`recorder.topics`. :func:`record_run` writes a run, :func:`read_log`
reads one back, whole or up to where it was cut or damaged.
"""

from __future__ import annotations

from recorder.reader import Integrity, LogChannel, LogContents, LogMessage, read_log
from recorder.session import Progress, RecordResult, RecordSettings, record_run
from recorder.topics import FORMAT_VERSION, METADATA_RESULT, METADATA_RUN, TOPICS, Topic
from recorder.writer import LogWriter

__all__ = [
    "FORMAT_VERSION",
    "METADATA_RESULT",
    "METADATA_RUN",
    "TOPICS",
    "Integrity",
    "LogChannel",
    "LogContents",
    "LogMessage",
    "LogWriter",
    "Progress",
    "RecordResult",
    "RecordSettings",
    "Topic",
    "read_log",
    "record_run",
]
