"""The log's message types: the committed generated code matches the .proto, and
every message type survives a trip through a log file unchanged."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from google.protobuf.descriptor import FieldDescriptor
from google.protobuf.message_factory import GetMessageClass

from pipemap.recorder import TOPICS, LogWriter, read_log, schemas
from pipemap.recorder.schemas import pipemap_log_pb2

SCHEMAS = Path(pipemap_log_pb2.__file__).parent


def test_generated_module_matches_the_proto(tmp_path: Path) -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "grpc_tools.protoc",
            f"-I{SCHEMAS}",
            f"--python_out={tmp_path}",
            "pipemap_log.proto",
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    spec = importlib.util.spec_from_file_location("fresh_pb2", tmp_path / "pipemap_log_pb2.py")
    assert spec is not None and spec.loader is not None
    # The fresh module registers the same file name in the default pool; compare the
    # descriptors' serialized form instead of importing it side by side.
    text = (tmp_path / "pipemap_log_pb2.py").read_text()
    start = text.index("AddSerializedFile(b'") + len("AddSerializedFile(b'")
    end = text.index("')", start)
    fresh = eval("b'" + text[start:end] + "'")  # the compiler's own bytes literal
    assert fresh == pipemap_log_pb2.DESCRIPTOR.serialized_pb, (
        "recorder/schemas/pipemap_log_pb2.py is stale: regenerate it (see schemas/__init__.py)"
    )


def _is_repeated(field: FieldDescriptor) -> bool:
    if hasattr(field, "is_repeated"):  # protobuf >= 6
        return bool(field.is_repeated)
    return bool(field.label == FieldDescriptor.LABEL_REPEATED)


def _filled(message_class: Any, depth: int = 0) -> Any:
    """A message with every field set to a value other than its default."""
    message = message_class()
    for i, field in enumerate(message_class.DESCRIPTOR.fields, start=1):
        repeated = _is_repeated(field)
        if field.type == FieldDescriptor.TYPE_MESSAGE:
            if depth > 2:
                continue
            if repeated:
                getattr(message, field.name).append(
                    _filled(GetMessageClass(field.message_type), depth + 1)
                )
            else:
                getattr(message, field.name).CopyFrom(
                    _filled(GetMessageClass(field.message_type), depth + 1)
                )
            continue
        value: Any
        if field.type in (FieldDescriptor.TYPE_DOUBLE, FieldDescriptor.TYPE_FLOAT):
            value = 0.25 * i + 0.5
        elif field.type == FieldDescriptor.TYPE_BOOL:
            value = True
        elif field.type == FieldDescriptor.TYPE_STRING:
            value = f"value {i}"
        elif field.type == FieldDescriptor.TYPE_BYTES:
            value = bytes([i, 255 - i, 0, 7])
        elif field.type == FieldDescriptor.TYPE_ENUM:
            value = field.enum_type.values[-1].number
        else:
            value = i * 1_000_000_007 % (2**31)  # integers
        if repeated:
            getattr(message, field.name).append(value)
        else:
            setattr(message, field.name, value)
    return message


@pytest.mark.parametrize("topic,message_class", TOPICS, ids=[t for t, _ in TOPICS])
def test_every_message_type_round_trips_through_a_log(
    tmp_path: Path, topic: str, message_class: Any
) -> None:
    original = _filled(message_class)
    assert original != message_class()  # something to lose
    path = tmp_path / "one.mcap"
    with path.open("wb") as f, LogWriter(f, {"pipemap_version": "test"}) as writer:
        writer.write(topic, 5_000_000_000, original)
    contents = read_log(path)
    [message] = contents.messages
    assert (message.topic, message.log_time_ns, message.sequence) == (topic, 5_000_000_000, 0)
    assert message_class.FromString(message.data) == original
    schema = {c.topic: c.schema_name for c in contents.channels.values()}[topic]
    assert schema == message_class.DESCRIPTOR.full_name


def test_a_topic_takes_only_its_own_message_type(tmp_path: Path) -> None:
    with (tmp_path / "x.mcap").open("wb") as f, LogWriter(f, {}) as writer:
        with pytest.raises(ValueError, match="carries"):
            writer.write("/robot/imu", 0, schemas.Ranges())
        with pytest.raises(ValueError, match="no such topic"):
            writer.write_serialized("/robot/unknown", 0, b"")
