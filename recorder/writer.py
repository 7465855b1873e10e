"""The log writer: an MCAP file of protobuf messages, finalised whatever happens.

One file per run: zstd chunks with CRCs, a data-section CRC, and a summary with
statistics and indexes. Every channel is registered up front, in the order of
:data:`recorder.topics.TOPICS`; each message's sequence number counts its topic's
messages from 0; log and publish time are both the run's simulated time. Nothing
depends on the wall clock, so the same run writes the same bytes.

:class:`LogWriter` is a context manager: leaving the block by an exception or
Ctrl-C still writes the summary, so the file is valid with everything written so
far; its result metadata then says how the run ended.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import TracebackType
from typing import Any, BinaryIO

from mcap.well_known import MessageEncoding
from mcap.writer import CompressionType, IndexType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import build_file_descriptor_set

from pipemap.recorder.topics import (
    FORMAT_VERSION,
    LIBRARY,
    METADATA_RESULT,
    METADATA_RUN,
    PROFILE,
    TOPICS,
)

__all__ = ["DEFAULT_CHUNK_BYTES", "LogWriter"]

#: Uncompressed bytes per chunk. Chunks are also closed at the end of every sweep
#: (:meth:`LogWriter.flush`), so a hard kill loses at most the sweep in progress.
DEFAULT_CHUNK_BYTES = 1 << 20


class LogWriter:
    """Writes one run's log to ``output``, an open binary file.

    ``run_metadata`` (string keys and values) is written first as the
    ``pipemap.run`` metadata record, with the log format's ``format_version``; its
    ``pipemap_version`` also names the writing library in the file's header.
    """

    def __init__(
        self,
        output: BinaryIO,
        run_metadata: Mapping[str, str],
        chunk_bytes: int = DEFAULT_CHUNK_BYTES,
    ) -> None:
        self._output = output
        self._mcap = McapWriter(
            output,
            chunk_size=chunk_bytes,
            compression=CompressionType.ZSTD,
            enable_crcs=True,
            enable_data_crcs=True,
            # The full index set. Message indexes cost 16 uncompressed bytes per
            # message, but MCAP's indexed readers need them (the TypeScript reader
            # Foxglove is built on refuses a chunk index without them), and they tell
            # what a damaged chunk held.
            index_types=IndexType.ALL,
        )
        version = run_metadata.get("pipemap_version", "")
        self._mcap.start(profile=PROFILE, library=f"{LIBRARY} {version}".strip())
        self._channels: dict[str, int] = {}
        self._types: dict[str, str] = {}
        self._sequence: dict[str, int] = {}
        schema_ids: dict[str, int] = {}
        for topic, message_class in TOPICS:
            name = message_class.DESCRIPTOR.full_name
            if name not in schema_ids:
                schema_ids[name] = self._mcap.register_schema(
                    name=name,
                    encoding="protobuf",
                    data=build_file_descriptor_set(message_class).SerializeToString(),
                )
            self._channels[topic] = self._mcap.register_channel(
                topic=topic, message_encoding=MessageEncoding.Protobuf, schema_id=schema_ids[name]
            )
            self._types[topic] = name
            self._sequence[topic] = 0
        self._mcap.add_metadata(METADATA_RUN, {"format_version": FORMAT_VERSION, **run_metadata})
        self.messages = 0
        self._last_time_ns = 0
        self._finished = False

    def write(self, topic: str, log_time_ns: int, message: Any) -> None:
        """Append ``message`` on ``topic`` at ``log_time_ns`` (simulated time)."""
        name = type(message).DESCRIPTOR.full_name
        if self._types.get(topic) != name:
            raise ValueError(f"topic {topic} carries {self._types.get(topic)}, not {name}")
        self.write_serialized(topic, log_time_ns, message.SerializeToString())

    def write_serialized(self, topic: str, log_time_ns: int, data: bytes) -> None:
        """Append a message already serialized as ``topic``'s message type."""
        if self._finished:
            raise RuntimeError("log already finished")
        if topic not in self._channels:
            raise ValueError(f"no such topic in the log format: {topic}")
        if log_time_ns < 0:
            raise ValueError(f"log time must be >= 0 ns, got {log_time_ns}")
        self._mcap.add_message(
            channel_id=self._channels[topic],
            log_time=log_time_ns,
            publish_time=log_time_ns,
            data=data,
            sequence=self._sequence[topic],
        )
        self._sequence[topic] += 1
        self.messages += 1
        self._last_time_ns = max(self._last_time_ns, log_time_ns)

    def count(self, topic: str) -> int:
        """Messages written on ``topic`` so far."""
        return self._sequence[topic]

    def flush(self) -> None:
        """Close the chunk in progress and hand everything to the operating system."""
        if not self._finished:
            self._mcap.flush()  # type: ignore[no-untyped-call]

    def finish(self, result_metadata: Mapping[str, str] | None = None) -> None:
        """Write the result metadata, the summary and the footer. Idempotent."""
        if self._finished:
            return
        if result_metadata is not None:
            self._mcap.add_metadata(METADATA_RESULT, dict(result_metadata))
        self._mcap.finish()  # type: ignore[no-untyped-call]
        self._output.flush()
        self._finished = True

    @property
    def finished(self) -> bool:
        """True once the summary and footer are written."""
        return self._finished

    def __enter__(self) -> LogWriter:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.finish()
            return
        reason = "interrupted" if issubclass(exc_type, KeyboardInterrupt) else "failed"
        self.finish({"status": reason, "error": f"{exc_type.__name__}: {exc}"[:500]})
