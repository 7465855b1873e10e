"""The columnar protobuf decoder gives what the generated classes give, field by field."""

from __future__ import annotations

import numpy as np
import pytest

from pipemap.errors import LogFormatError
from pipemap.recorder import schemas
from pipemap.recorder.messages import pose_message
from pipemap.replay.wire import decode_columns, spec_of


def test_flat_messages_with_zero_fields_left_out() -> None:
    messages = [
        schemas.Ranges(time_ns=0, front_m=0.5, front_left_m=0.0, front_right_m=1.2),
        schemas.Ranges(time_ns=2**40 + 7, front_m=0.0, front_left_m=-0.25, max_range_m=1.2),
        schemas.Ranges(),  # every field zero: an empty payload
    ]
    columns = decode_columns(
        [m.SerializeToString() for m in messages], spec_of(schemas.Ranges.DESCRIPTOR)
    )
    for name in ("time_ns", "front_m", "front_left_m", "front_right_m", "max_range_m"):
        expected = np.array([getattr(m, name) for m in messages], dtype=np.float64)
        assert np.array_equal(columns[name].astype(np.float64), expected), name
    assert columns["time_ns"].dtype == np.int64
    assert columns["time_ns"][1] == 2**40 + 7


def test_negative_varints_nested_messages_and_strings() -> None:
    wheels = [schemas.WheelEncoders(left_ticks=-5, right_ticks=2**35), schemas.WheelEncoders()]
    columns = decode_columns(
        [m.SerializeToString() for m in wheels], spec_of(schemas.WheelEncoders.DESCRIPTOR)
    )
    assert columns["left_ticks"].tolist() == [-5, 0]
    assert columns["right_ticks"].tolist() == [2**35, 0]

    poses = [pose_message(10**9 * i, 0.1 * i, -0.2 * i, 0.3 * i) for i in range(5)]
    columns = decode_columns(
        [p.SerializeToString() for p in poses], spec_of(schemas.FrameTransform.DESCRIPTOR)
    )
    for axis in "xyz":
        expected = [getattr(p.translation, axis) for p in poses]
        assert columns[f"translation.{axis}"].tolist() == expected
    for axis in "xyzw":
        assert columns[f"rotation.{axis}"].tolist() == [getattr(p.rotation, axis) for p in poses]
    assert columns["timestamp.seconds"].tolist() == [0, 1, 2, 3, 4]
    assert columns.strings("child_frame_id") == ["robot"] * 5

    states = ["following", "following", "turning", "", "turning", "turning"]
    messages = [schemas.ControllerState(state=s, linear_mps=0.1) for s in states]
    payloads = [m.SerializeToString() for m in messages]
    columns = decode_columns(payloads, spec_of(schemas.ControllerState.DESCRIPTOR, only=["state"]))
    assert set(columns.values) == {"state.offset", "state.length"}  # the rest is skipped
    assert columns.strings("state") == states
    assert columns.changes("state").tolist() == [0, 2, 3, 4]
    changed = columns.strings("state", columns.changes("state"))
    assert changed == ["following", "turning", "", "turning"]


def test_a_cut_payload_is_a_log_format_error() -> None:
    payload = schemas.Imu(time_ns=123456789, yaw_rate_rps=0.5).SerializeToString()
    with pytest.raises(LogFormatError):
        decode_columns([payload[:-2]], spec_of(schemas.Imu.DESCRIPTOR))
