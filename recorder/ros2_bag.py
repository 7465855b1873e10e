"""A ROS 2 bag read as raw CDR messages: MCAP storage by pipemap's own MCAP walk
(which keeps everything up to where a file is cut short or damaged), SQLite
storage by the ``rosbags`` library's reader. Messages are decoded with ``rosbags``'
type store of ROS 2 Humble's message definitions.

``rosbags`` is an optional dependency (``pipemap[ros]``): it is imported when a bag
is read, so that nothing else of pipemap needs it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pipemap.errors import InputError
from pipemap.recorder.filebytes import FileBytes
from pipemap.recorder.mcapfile import McapHeaderError, Walk

__all__ = ["BagMessages", "read_bag", "typestore"]


def typestore() -> Any:
    """``rosbags``' type store of ROS 2 Humble (every standard message type);
    an :class:`InputError` saying how to install it where ``rosbags`` is missing."""
    try:
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError(
            "reading and writing ROS 2 bags needs the rosbags library: pip install 'pipemap[ros]'"
        ) from None
    return get_typestore(Stores.ROS2_HUMBLE)


@dataclass
class BagMessages:
    """The messages of a bag's wanted topics, in the bag's order, and what it holds."""

    #: Every topic of the bag and its message type.
    types: dict[str, str] = field(default_factory=dict)
    #: Messages of every topic of the bag.
    counts: dict[str, int] = field(default_factory=dict)
    #: (topic, receive time in ns, CDR bytes) of the wanted topics.
    messages: list[tuple[str, int, bytes]] = field(default_factory=list)
    #: How the bag stops early or is damaged ("" when it is whole).
    cut_short: str = ""


def _storage_files(bag: Path) -> tuple[str, list[Path]]:
    """The bag's storage kind (``mcap`` or ``sqlite3``) and its files, in order."""
    if not bag.exists():
        raise InputError(f"{bag}: no such file or folder")
    files = [bag] if bag.is_file() else sorted(bag.glob("*.mcap")) or sorted(bag.glob("*.db3"))
    if not files or files[0].suffix not in (".mcap", ".db3"):
        raise InputError(f"{bag}: not a rosbag2 bag (no .mcap or .db3 storage file)")
    return ("mcap" if files[0].suffix == ".mcap" else "sqlite3"), files


def read_bag(bag: str | Path, wanted: set[str]) -> BagMessages:
    """Read the bag (a rosbag2 folder, or one of its storage files) at ``bag``,
    keeping the messages of the ``wanted`` topics."""
    path = Path(bag)
    kind, files = _storage_files(path)
    out = BagMessages()
    if kind == "mcap":
        for file in files:
            _read_mcap(file, wanted, out)
    else:
        _read_sqlite(path, wanted, out)
    return out


def _read_mcap(file: Path, wanted: set[str], out: BagMessages) -> None:
    try:
        with file.open("rb") as handle:
            walk = Walk(FileBytes(handle))
            for topic, _sequence, time_ns, payload in walk:
                out.counts[topic] = out.counts.get(topic, 0) + 1
                if topic in wanted:
                    out.messages.append((topic, time_ns, payload))
            found = walk.scan
    except McapHeaderError as exc:
        raise InputError(f"{file}: not an MCAP storage file ({exc})") from None
    except OSError as exc:
        raise InputError(f"{file}: cannot read ({exc.strerror})") from None
    for topic, schema_id, encoding in found.channels.values():
        name, _ = found.schemas.get(schema_id, ("", ""))
        if encoding != "cdr":
            raise InputError(f"{topic}: message encoding {encoding!r}, not cdr")
        out.types[topic] = name
    if found.truncated and not out.cut_short:
        out.cut_short = f"{file}: cut short ({found.truncated})"
    elif found.lost and not out.cut_short:
        out.cut_short = f"{file}: damaged ({found.lost[0].problem})"


def _read_sqlite(bag: Path, wanted: set[str], out: BagMessages) -> None:
    typestore()  # says how to install rosbags, where it is missing
    from rosbags.rosbag2 import Reader

    try:
        with Reader(bag) as reader:
            for connection in reader.connections:
                out.types[connection.topic] = connection.msgtype
                out.counts[connection.topic] = out.counts.get(connection.topic, 0)
            try:
                for connection, time_ns, raw in reader.messages():
                    out.counts[connection.topic] += 1
                    if connection.topic in wanted:
                        out.messages.append((connection.topic, time_ns, bytes(raw)))
            except Exception as exc:  # the sqlite3 storage's errors are of many kinds
                out.cut_short = f"{bag}: cut short ({exc})"
    except InputError:
        raise
    except Exception as exc:
        raise InputError(f"{bag}: not a readable rosbag2 bag ({exc})") from None
