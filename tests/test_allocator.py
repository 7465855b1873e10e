"""``pipemap.allocator``: freed memory found again without page faults, the user's
own allocator settings left alone, and who calls it."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Mapping
from typing import Any

import pytest

from pipemap.batch import engine
from pipemap.cli import app

#: Arrays of the matcher's sizes made and freed again and again; prints whether the
#: allocator was set up and the page faults of the second half.
_PATTERN = """
import resource, sys
import numpy as np
from pipemap.allocator import keep_freed_memory
print(keep_freed_memory() if sys.argv[1] == "set" else None)
def churn():
    for _ in range(20):
        a = np.ones((6, 200, 400)); b = a * 2.0; c = np.ones(300_000); del a, b, c
churn()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
churn()
print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""

ON_GLIBC = sys.platform.startswith("linux") and str(
    os.confstr("CS_GNU_LIBC_VERSION") or ""
).startswith("glibc")


def _clean_env(**extra: str) -> dict[str, str]:
    env = {
        k: v for k, v in os.environ.items() if not k.startswith("MALLOC_") and k != "GLIBC_TUNABLES"
    }
    return {**env, **extra}


def _churn(mode: str, env: Mapping[str, str]) -> tuple[str, int]:
    out = subprocess.run(
        [sys.executable, "-c", _PATTERN, mode],
        env=dict(env),
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    return out[0], int(out[1])


def test_freed_arrays_are_found_again_without_page_faults() -> None:
    as_is, faults_as_is = _churn("leave", _clean_env())
    done, faults_set_up = _churn("set", _clean_env())
    assert as_is == "None"
    if not ON_GLIBC:
        assert done == "False"
        return
    assert done == "True"
    # 40 arrays of 3.7 MiB: each faults its pages in again as glibc leaves it.
    assert faults_as_is > 20_000
    assert faults_set_up < faults_as_is / 20


@pytest.mark.parametrize(
    "setting",
    [
        {"MALLOC_TOP_PAD_": "0"},
        {"MALLOC_TRIM_THRESHOLD_": "131072"},
        {"MALLOC_MMAP_THRESHOLD_": "131072"},
        {"GLIBC_TUNABLES": "glibc.malloc.trim_threshold=131072"},
    ],
)
def test_the_users_own_allocator_settings_stand(setting: dict[str, str]) -> None:
    done, _ = _churn("set", _clean_env(**setting))
    assert done == "False"


def test_other_glibc_tunables_do_not_stop_it() -> None:
    done, _ = _churn("set", _clean_env(GLIBC_TUNABLES="glibc.cpu.hwcap_mask=0"))
    assert done == ("True" if ON_GLIBC else "False")


def test_every_command_sets_the_allocator_up(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    monkeypatch.setattr(app, "keep_freed_memory", lambda: calls.append("set") or True)
    assert app.main(["info", "/nonexistent/run.mcap"]) == app.BAD_INPUT
    assert calls == ["set"]


def test_each_batch_task_sets_its_workers_allocator_up(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    monkeypatch.setattr(engine, "keep_freed_memory", lambda: calls.append("set") or True)

    def task(*args: Any, **kwargs: Any) -> Mapping[str, Any]:
        calls.append("task")
        return {}

    engine._one_thread(task)()
    assert calls == ["set", "task"]
