"""Many small protobuf messages of one type, decoded at once into numpy columns.

A view needs every value of the high-rate streams (some 80 000 messages in a
six-minute run) as arrays. Decoding them one by one with the generated classes
and reading their fields back into arrays took several times longer than the
replay itself; this decoder walks the protobuf wire format of all the messages
together, one field at a time, with numpy. It handles what pipemap's sensor
and pose messages use: varints (``int64``, ``uint32``, ``bool``, enums),
``float``, ``double``, nested messages and length-delimited ``string`` or
``bytes`` fields (given as offsets into the joined payloads). Fields absent
from a message (proto3 leaves zeros out) read 0; fields not asked for are
skipped. A malformed payload raises :class:`pipemap.errors.LogFormatError`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Union

import numpy as np

from pipemap.errors import LogFormatError

__all__ = ["Columns", "FieldSpec", "decode_columns", "spec_of"]

#: A field's kind (``"varint"``, ``"float"``, ``"double"``, ``"bytes"``) or, for a
#: nested message, the spec of its fields; keyed by field number, with a name.
FieldSpec = Mapping[int, tuple[str, Union[str, "FieldSpec"]]]

_VARINT, _FIXED64, _LENGTH, _FIXED32 = 0, 1, 2, 5
_WIRE_OF_KIND = {"varint": _VARINT, "double": _FIXED64, "float": _FIXED32, "bytes": _LENGTH}
_MAX_VARINT_BYTES = 10
#: Protobuf field types (``FieldDescriptor.TYPE_*``) by the kind this decoder reads.
_KIND_OF_TYPE = {
    1: "double",
    2: "float",
    3: "varint",  # int64
    4: "varint",  # uint64
    5: "varint",  # int32
    8: "varint",  # bool
    9: "bytes",  # string
    12: "bytes",
    13: "varint",  # uint32
    14: "varint",  # enum
}


@dataclass(frozen=True)
class Columns:
    """Decoded fields by dotted name (``translation.x``), one row per message.

    A ``bytes`` field ``name`` gives ``name.offset`` and ``name.length`` into
    :attr:`data`; :meth:`strings` turns them into text.
    """

    data: np.ndarray
    values: dict[str, np.ndarray]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.values[name]

    def changes(self, name: str) -> np.ndarray:
        """The rows whose ``bytes``/``string`` field ``name`` differs from the row
        before (row 0 included), compared byte for byte without making strings."""
        offsets, lengths = self.values[f"{name}.offset"], self.values[f"{name}.length"]
        if len(offsets) == 0:
            return np.zeros(0, dtype=np.int64)
        width = int(lengths.max())
        at = offsets[:, None] + np.arange(width)
        inside = np.arange(width) < lengths[:, None]
        text = np.where(inside, self.data[np.minimum(at, len(self.data) - 1)], 0)
        differs = np.any(text[1:] != text[:-1], axis=1) | (lengths[1:] != lengths[:-1])
        return np.concatenate([[0], 1 + np.nonzero(differs)[0]])

    def strings(self, name: str, rows: np.ndarray | None = None) -> list[str]:
        """The text of the ``bytes``/``string`` field ``name`` of every message, or of
        the messages ``rows``."""
        raw = self.data.tobytes()
        offsets, lengths = self.values[f"{name}.offset"], self.values[f"{name}.length"]
        if rows is not None:
            offsets, lengths = offsets[rows], lengths[rows]
        return [
            raw[o : o + n].decode("utf-8", "replace")
            for o, n in zip(offsets.tolist(), lengths.tolist(), strict=True)
        ]


def _varint(data: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The varints starting at ``pos`` and the positions after them."""
    if pos.size and pos.max() >= len(data):
        raise LogFormatError("a message ends before a varint")
    first = data[pos]
    if not np.any(first & 0x80):  # one byte each: field keys, small numbers
        return first.astype(np.uint64), pos + 1
    # Up to ten bytes of every varint at once; a varint ends at its first byte < 0x80.
    at = np.minimum(pos[:, None] + np.arange(_MAX_VARINT_BYTES), len(data) - 1)
    window = data[at]
    last = (window & 0x80) == 0
    if not np.all(last.any(axis=1)):
        raise LogFormatError("a varint longer than 10 bytes")
    length = np.argmax(last, axis=1) + 1
    if np.any(pos + length > len(data)):
        raise LogFormatError("a message ends inside a varint")
    value = np.zeros(len(pos), dtype=np.uint64)
    for k in range(int(length.max())):
        part = np.where(k < length, window[:, k] & 0x7F, 0).astype(np.uint64)
        value |= part << np.uint64(7 * k)
    return value, pos + length


def _fixed(data: np.ndarray, pos: np.ndarray, dtype: str) -> np.ndarray:
    size = np.dtype(dtype).itemsize
    if pos.size and pos.max() + size > len(data):
        raise LogFormatError("a message ends inside a fixed-size field")
    raw = data[pos[:, None] + np.arange(size)]
    return np.ascontiguousarray(raw).view(dtype).reshape(-1)


def _empty(spec: FieldSpec, n: int, prefix: str, out: dict[str, np.ndarray]) -> None:
    for name, kind in spec.values():
        if isinstance(kind, str):
            if kind == "bytes":
                out[f"{prefix}{name}.offset"] = np.zeros(n, dtype=np.int64)
                out[f"{prefix}{name}.length"] = np.zeros(n, dtype=np.int64)
            else:
                dtype = np.int64 if kind == "varint" else np.float64
                out[f"{prefix}{name}"] = np.zeros(n, dtype=dtype)
        else:
            _empty(kind, n, f"{prefix}{name}.", out)


def _decode(
    data: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    spec: FieldSpec,
    prefix: str,
    out: dict[str, np.ndarray],
    rows: np.ndarray,
) -> None:
    """Decode the messages ``data[starts:ends]`` into ``out`` at ``rows``."""
    pos = starts.copy()
    active = np.nonzero(pos < ends)[0]
    while active.size:
        key, after = _varint(data, pos[active])
        same = key.min() == key.max()  # the usual case: every message has the same next field
        for k in [int(key[0])] if same else np.unique(key).tolist():
            number, wire = k >> 3, k & 7
            if same:
                at, q = active, after
            else:
                chosen = key == k
                at, q = active[chosen], after[chosen]
            name, kind = spec.get(number, ("", ""))
            if isinstance(kind, str) and kind and _WIRE_OF_KIND[kind] != wire:
                raise LogFormatError(f"field {prefix}{name} has wire type {wire}")
            if wire == _VARINT:
                value, q = _varint(data, q)
                if kind:
                    out[f"{prefix}{name}"][rows[at]] = value.view(np.int64)
            elif wire in (_FIXED64, _FIXED32):
                dtype = "<f8" if wire == _FIXED64 else "<f4"
                if kind:
                    out[f"{prefix}{name}"][rows[at]] = _fixed(data, q, dtype)
                q = q + np.dtype(dtype).itemsize
            elif wire == _LENGTH:
                length, q = _varint(data, q)
                size = length.astype(np.int64)
                if kind == "bytes":
                    out[f"{prefix}{name}.offset"][rows[at]] = q
                    out[f"{prefix}{name}.length"][rows[at]] = size
                elif kind:
                    assert not isinstance(kind, str)
                    _decode(data, q, q + size, kind, f"{prefix}{name}.", out, rows[at])
                q = q + size
            else:
                raise LogFormatError(f"unsupported protobuf wire type {wire}")
            pos[at] = q
        if np.any(pos > ends):
            raise LogFormatError("a field runs past the end of its message")
        active = np.nonzero(pos < ends)[0]


def spec_of(descriptor: Any, only: Sequence[str] | None = None) -> FieldSpec:
    """The spec of the fields of a protobuf message type (its ``DESCRIPTOR``): every
    field, or the top-level fields named in ``only``."""
    spec: dict[int, tuple[str, str | FieldSpec]] = {}
    for field in descriptor.fields:
        if field.is_repeated or (only is not None and field.name not in only):
            continue  # not needed by the view; skipped when met
        kind = _KIND_OF_TYPE.get(field.type)
        if field.type == field.TYPE_MESSAGE:
            spec[field.number] = (field.name, spec_of(field.message_type))
        elif kind is not None:
            spec[field.number] = (field.name, kind)
    return spec


def decode_columns(payloads: Sequence[bytes], spec: FieldSpec) -> Columns:
    """Decode every payload (a serialized message of one type) by ``spec``."""
    lengths = np.fromiter(map(len, payloads), dtype=np.int64, count=len(payloads))
    ends = np.cumsum(lengths)
    starts = ends - lengths
    data = np.frombuffer(b"".join(payloads), dtype=np.uint8)
    out: dict[str, np.ndarray] = {}
    _empty(spec, len(payloads), "", out)
    _decode(data, starts, ends, spec, "", out, np.arange(len(payloads)))
    return Columns(data, out)
