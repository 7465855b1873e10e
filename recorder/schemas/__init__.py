"""Protobuf message classes of the log: pipemap's own and Foxglove's well-known ones.

``pipemap_log.proto`` is the source of pipemap's own messages. Its Python module,
``pipemap_log_pb2.py``, is generated and committed so that installing pipemap needs
no protobuf compiler. Regenerate it after editing the ``.proto`` (grpcio-tools
1.71 writes code that protobuf 5.29 and every later runtime accept)::

    pip install grpcio-tools==1.71.0
    cd recorder/schemas && python -m grpc_tools.protoc -I. --python_out=. \\
        --pyi_out=. pipemap_log.proto

``tests/recorder/test_schemas.py`` compiles the ``.proto`` again and fails while
the committed module describes anything else.
"""

from __future__ import annotations

from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.Log_pb2 import Log
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

from pipemap.recorder.schemas.pipemap_log_pb2 import (
    ControllerState,
    Decision,
    Imu,
    NodeEvent,
    ProbeResult,
    Ranges,
    SweepCommand,
    TrueSweep,
    WheelEncoders,
)

__all__ = [
    "CompressedImage",
    "ControllerState",
    "Decision",
    "FrameTransform",
    "Imu",
    "Log",
    "NodeEvent",
    "ProbeResult",
    "Ranges",
    "SceneUpdate",
    "SweepCommand",
    "TrueSweep",
    "WheelEncoders",
]
