"""Output files written whole or not at all, shared by every layer that writes one.

A file is written under a temporary name in its own folder (``.NAME.XXXX.partial``)
and renamed onto its name only when every byte is written, so that a full disk, a
kill or a stop signal part-way never leaves a half-written map, table or image under
the asked name, and an earlier file of that name stays as it was until then. The
rename is one step on POSIX file systems. A device or a FIFO given as the output
(``/dev/null``) is written in place, never replaced. The standard library and the error root
only, so that every layer may use it.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterator, Mapping
from pathlib import Path

from pipemap.errors import WriteError

__all__ = ["partial_path", "write_all", "write_whole"]


def _new_partial(path: Path) -> Path:
    """Make an empty file of a fresh name beside ``path``, with the permissions a new
    file of the process gets (``mkstemp`` would make it private)."""
    for _ in range(100):
        partial = path.with_name(f".{path.name}.{secrets.token_hex(4)}.partial")
        try:
            os.close(os.open(partial, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            continue
        except OSError as exc:
            raise WriteError(f"{path}: cannot write ({exc.strerror or exc})") from None
        return partial
    raise WriteError(f"{path}: cannot write (no free temporary name beside it)")


@contextlib.contextmanager
def partial_path(path: Path | str, replace: bool = True) -> Iterator[Path]:
    """A fresh temporary path beside ``path``, for a writer that takes a file name;
    renamed onto ``path`` when the block ends normally, removed otherwise. A failure
    to rename is a :class:`WriteError`. With ``replace`` false an existing ``path``
    is never replaced: that is a :class:`FileExistsError`."""
    path = Path(path)
    if path.exists() and not path.is_file():
        # A device or a FIFO (/dev/null, a named pipe): written in place, never
        # replaced by a regular file of its name.
        yield path
        return
    partial = _new_partial(path)
    try:
        yield partial
        try:
            if replace:
                os.replace(partial, path)
            else:
                os.link(partial, path)  # one step that fails if ``path`` exists
        except FileExistsError:
            raise
        except OSError as exc:
            raise WriteError(f"{path}: cannot write ({exc.strerror or exc})") from None
    finally:
        with contextlib.suppress(OSError):
            partial.unlink()


def write_whole(path: Path | str, data: bytes | str, replace: bool = True) -> None:
    """Write ``data`` (text as UTF-8) to ``path`` whole or not at all; a failure (a
    full disk, the file size limit) is a :class:`WriteError` naming the file. With
    ``replace`` false an existing ``path`` is a :class:`FileExistsError`."""
    write_all({Path(path): data}, replace)


def write_all(files: Mapping[Path, bytes | str], replace: bool = True) -> None:
    """Write every one of ``files`` (path: data, text as UTF-8) whole, or none of them:
    each goes to its temporary name, and they are renamed onto their names only once
    every one is written, so a disk that fills at the second leaves no first one
    without it. A failure is a :class:`WriteError` naming the file it hit."""
    with contextlib.ExitStack() as renames:
        for path, data in files.items():
            payload = data.encode("utf-8") if isinstance(data, str) else data
            try:
                partial = renames.enter_context(partial_path(path, replace))
                with partial.open("wb") as stream:
                    stream.write(payload)
            except (FileExistsError, WriteError):
                raise
            except OSError as exc:
                raise WriteError(f"{path}: cannot write ({exc.strerror or exc})") from None
