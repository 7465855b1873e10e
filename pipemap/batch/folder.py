"""A batch's output folder before any run: may it be written, and what does ``--resume``
keep?

``--resume`` continues the batch a folder holds, never another one: the folder's own
``spec.toml`` must give the same runs (the same keys' values, the same combinations)
and the same description as the SPEC given, or nothing is touched and the error names
every key that differs. A SPEC that only reformats or recomments the folder's resumes.
Every run whose folder is whole keeps its row, failed ones included, until it is made
again.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from pipemap.batch.results import read_result
from pipemap.batch.spec import GRID_KEYS, BatchSpec, parse_spec
from pipemap.errors import InputError

__all__ = ["check_out", "finished_results", "spec_differences"]

#: The file of a batch folder that holds the SPEC its runs were made by.
SPEC_FILE = "spec.toml"


def _values(values: Iterable[Any]) -> str:
    shown = sorted({repr(v) if isinstance(v, str) else str(v) for v in values})
    return ", ".join(shown) if len(shown) <= 4 else ", ".join(shown[:4]) + ", ..."


def spec_differences(there: BatchSpec, here: BatchSpec) -> list[str]:
    """What differs between two SPECs' runs, one entry per key (``key (values there;
    values here)``); empty when they make the same runs with the same description."""
    keys = []
    for key in GRID_KEYS:
        old = {getattr(p, key) for p in there.points}
        new = {getattr(p, key) for p in here.points}
        if old != new:
            keys.append(f"{key} ({_values(old)} there; {_values(new)} here)")
    same_runs = {p.run_id for p in there.points} == {p.run_id for p in here.points}
    if not same_runs and not keys:
        keys.append("the runs (the same values, combined into other runs)")
    return (["description"] if there.description != here.description else []) + keys


def _folder_spec(out: Path) -> BatchSpec | None:
    """The SPEC a batch folder was made by; ``None`` for a folder without one that
    holds nothing (a batch may start there)."""
    path = out / SPEC_FILE
    if not path.is_file():
        if any(out.iterdir()):
            raise InputError(
                f"--resume: {out} has no {SPEC_FILE}: it is not a batch folder, "
                "nothing there to resume (give another --out)"
            )
        return None
    try:
        return parse_spec(path.read_text(encoding="utf-8"), str(path))
    except (InputError, UnicodeDecodeError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise InputError(f"--resume: {out}'s {SPEC_FILE} is not a valid SPEC: {first}") from None


def _check_same_spec(spec: BatchSpec, out: Path) -> None:
    there = _folder_spec(out)
    if there is None:
        return
    differences = spec_differences(there, spec)
    if differences:
        raise InputError(
            f"--resume: {out} holds the runs of another SPEC, which differs in "
            f"{'; '.join(differences)}; resume it with its own {out / SPEC_FILE}, "
            "or give another --out (--force replaces its runs)"
        )


def check_out(spec: BatchSpec, out: Path, resume: bool, force: bool) -> None:
    """Whether ``out`` may take ``spec``'s batch: a folder whose parent exists, empty,
    or resumed (made by the same runs), or replaced (``force``). Reads, writes nothing."""
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: is a file, not a folder")
    if not out.parent.is_dir():
        raise InputError(f"--out {out}: folder {out.parent} does not exist")
    if out.is_dir() and any(out.iterdir()) and not (resume or force):
        raise InputError(
            f"--out {out}: exists; refusing to touch it without --resume (keep its "
            "finished runs) or --force (start afresh)"
        )
    if resume and out.is_dir():
        _check_same_spec(spec, out)


def finished_results(spec: BatchSpec, out: Path) -> dict[str, dict[str, Any]]:
    """The ``result.json`` of every run of ``spec`` whose folder in ``out`` is whole,
    complete or failed, by run id."""
    found = {}
    for point in spec.points:
        doc = read_result(out, point.run_id)
        if doc is not None:
            found[point.run_id] = doc
    return found
