"""Where commands write: every output path checked before any work, the same way.

:func:`output_file` and :func:`output_folder` are called by every command that
writes (``record -o``, ``replay -o/--graphml``, ``view --save``, ``score
--save-results``, ``sim --save-sweeps``, ``experiment --out``) before it reads a log
or starts a simulation: the folder must exist and be writable, and what is there
already is replaced only with ``--force``. Whether a folder can be written is tried
(a temporary file is made and removed), not guessed from permission bits, which
say yes to root even where a read-only mount or a special file system says no.
:func:`write_text` turns a failure while writing (a full disk) into one line.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from pipemap.errors import InputError
from pipemap.wholefile import write_whole

__all__ = ["output_file", "output_folder", "write_text"]


def _unwritable_folder(folder: Path) -> str:
    """Why no file can be made in ``folder`` ("" when one can)."""
    try:
        with tempfile.TemporaryFile(dir=folder, prefix=".pipemap-check-"):
            return ""
    except OSError as exc:
        return exc.strerror or type(exc).__name__


def _unwritable_file(path: Path) -> str:
    """Why the existing file ``path`` cannot be opened for writing ("" when it can).
    Opened without truncation, so its content stays as it is."""
    try:
        os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
    except OSError as exc:
        return exc.strerror or type(exc).__name__
    return ""


def output_file(path: str | None, flag: str, force: bool) -> Path | None:
    """``path`` (given as ``flag``) as a file this command may write; ``None`` stays
    ``None``."""
    if path is None:
        return None
    target = Path(path)
    where = f"{flag} {target}"
    if target.is_dir():
        raise InputError(f"{where}: is a folder, not a file")
    folder = target.parent
    if not folder.is_dir():
        raise InputError(f"{where}: folder {folder} does not exist")
    if target.exists():
        if not force:
            raise InputError(f"{where}: exists; refusing to overwrite without --force")
        reason = _unwritable_file(target)
        if reason:
            raise InputError(f"{where}: cannot be written ({reason})")
    else:
        reason = _unwritable_folder(folder)
        if reason:
            raise InputError(f"{where}: cannot write in folder {folder} ({reason})")
    return target


def output_folder(
    path: str, flag: str, force: bool, earlier: Callable[[Path], list[str]] | None = None
) -> Path:
    """``path`` (given as ``flag``) as a folder this command may fill (made later if it
    does not exist; its parent must, as a file's folder must). ``earlier`` lists what
    of a folder's content the command would replace (default: anything in it); that
    needs ``force``."""
    folder = Path(path)
    where = f"{flag} {folder}"
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{where}: is a file, not a folder")
    existing = folder if folder.is_dir() else folder.parent
    if not existing.is_dir():
        raise InputError(f"{where}: folder {existing} does not exist")
    if folder.is_dir():
        found = earlier(folder) if earlier is not None else sorted(p.name for p in folder.iterdir())
        if found and not force:
            raise InputError(
                f"{where}: holds earlier results ({found[0]}); refusing to replace them "
                "without --force"
            )
    reason = _unwritable_folder(existing)
    if reason:
        raise InputError(f"{where}: cannot write in folder {existing} ({reason})")
    return folder


def write_text(target: Path, text: str) -> None:
    """Write ``text`` to ``target`` whole or not at all (:mod:`pipemap.wholefile`); a
    failure part-way is one line (exit status 3) and leaves no part of it there."""
    write_whole(target, text)
