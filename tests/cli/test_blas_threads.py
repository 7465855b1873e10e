"""Every command runs numpy's matrix products on one thread, unless the user sized the
BLAS pool; and nothing loads numpy before the command has said so."""

from __future__ import annotations

import subprocess
import sys

import pytest

from pipemap.cli import app


@pytest.fixture
def no_blas_settings(monkeypatch: pytest.MonkeyPatch) -> None:
    for name in app.BLAS_THREAD_SETTINGS:
        monkeypatch.delenv(name, raising=False)


def test_a_command_asks_for_one_blas_thread(no_blas_settings: None) -> None:
    import os

    assert app.main(["info", "/nonexistent/run.mcap"]) == app.BAD_INPUT
    assert os.environ["OPENBLAS_NUM_THREADS"] == "1"
    assert os.environ["MKL_NUM_THREADS"] == "1"


@pytest.mark.parametrize("name", app.BLAS_THREAD_SETTINGS)
def test_the_users_own_thread_setting_stands(
    no_blas_settings: None, monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    import os

    monkeypatch.setenv(name, "2")
    assert app.one_blas_thread() is False
    assert os.environ[name] == "2"
    assert all(os.environ.get(other) is None for other in app.BLAS_THREAD_SETTINGS if other != name)


def test_numpy_is_not_loaded_before_the_setting() -> None:
    # OpenBLAS reads its thread count when numpy loads it: later settings are ignored.
    code = "import sys, pipemap.cli; print('numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_match_imports_no_log_layer() -> None:
    # The image-set commands read no log: mcap, protobuf and the replay load on demand.
    code = (
        "import sys, pipemap.api as api, pipemap.cli.folder_commands;"
        "print('pipemap.replay' in sys.modules, 'pipemap.recorder' in sys.modules);"
        "print(api.Integrity.OK.name, api.ScoreReport.__name__)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False", "OK", "ScoreReport"]
