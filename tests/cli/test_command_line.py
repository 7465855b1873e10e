"""The ``pipemap`` command line: bad flags and values (exit status 2, one
``pipemap: error:`` line naming the value, never a traceback, in-process and as a real
process), ``--help`` and ``--version``, the parser's presets, its lazy imports and its
commands.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.cli.common import assert_one_error, make_set, run, run_subprocess

# ---------------------------------------------------------------- bad input: the command line


def test_unknown_flag(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = make_set(tmp_path, "a", seed=1)
    status, out, err = run(["match", str(good), "--bogus"], capfd)
    assert_one_error(status, out, err, "--bogus")


@pytest.mark.parametrize("value", ["2", "abc", "nan", "-1.5"])
def test_bad_threshold(value: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    good = make_set(tmp_path, "a", seed=1)
    status, out, err = run(["match", str(good), "--threshold", value], capfd)
    line = assert_one_error(status, out, err, "--threshold")
    assert line.rstrip("'\"").endswith(value), line  # the bad value, as typed


@pytest.mark.parametrize(
    ("flag", "value"),
    [
        ("--downsample", "0"),
        ("--fov-deg", "400"),
        ("--keep-top", "0"),
        ("--zoom", "1.2,0.9"),
        ("--zoom", "x"),
        ("--highpass", "2"),
    ],
)
def test_bad_matching_option(
    flag: str, value: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    good = make_set(tmp_path, "a", seed=1)
    status, out, err = run(["map", str(good), flag, value], capfd)
    line = assert_one_error(status, out, err, flag)
    assert line.endswith(value), line


def test_command_without_folders(capfd: pytest.CaptureFixture[str]) -> None:
    status, out, err = run(["map"], capfd)
    assert_one_error(status, out, err, "DIR")


def test_help_exits_zero(capfd: pytest.CaptureFixture[str]) -> None:
    status, out, err = run(["--help"], capfd)
    assert status == 0
    assert out.startswith("usage: pipemap")
    assert "match" in out and "map" in out
    assert err == ""


def test_version(capfd: pytest.CaptureFixture[str]) -> None:
    from pipemap import __version__

    status, out, err = run(["--version"], capfd)
    assert status == 0
    assert out.strip() == f"pipemap {__version__}"


# ---------------------------------------------------------------- as a real process


@pytest.mark.parametrize("case", ["missing", "corrupt", "threshold"])
def test_subprocess_error_has_no_traceback(case: str, tmp_path: Path) -> None:
    good = make_set(tmp_path, "a", seed=1)
    if case == "missing":
        named = str(tmp_path / "nowhere")
        argv = ["match", str(good), named]
    elif case == "corrupt":
        bad = make_set(tmp_path, "bad", seed=2)
        (bad / "camera_image3.png").write_bytes(np.random.default_rng(3).bytes(4096))
        named = str(bad / "camera_image3.png")
        argv = ["map", str(good), str(bad)]
    else:
        named = "abc"
        argv = ["match", str(good), "--threshold", named]
    done = run_subprocess(argv, cwd=tmp_path)
    assert_one_error(done.returncode, done.stdout, done.stderr, named)


def test_subprocess_match_json(tmp_path: Path) -> None:
    a = make_set(tmp_path, "a", seed=1)
    b = make_set(tmp_path, "b", seed=2)
    done = run_subprocess(["match", str(a), str(b), "--json"], cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    doc = json.loads(done.stdout)
    assert [(p["a"], p["b"]) for p in doc["pairs"]] == [(str(a), str(b))]


# ---------------------------------------------------------------- the parser


def test_robust_preset_fills_in_its_settings_and_threshold() -> None:
    from pipemap.cli.localizer_options import apply_presets, fast_config
    from pipemap.cli.parser import build_parser
    from pipemap.localizer.presets import (
        ROBUST_HIGHPASS_FRACTION,
        ROBUST_THRESHOLD,
        ROBUST_ZOOMS,
    )

    args = build_parser().parse_args(["score", "run.mcap", "--robust"])
    apply_presets(args)
    config = fast_config(args)
    assert (config.zooms, config.highpass_fraction, config.baseline) == (
        ROBUST_ZOOMS,
        ROBUST_HIGHPASS_FRACTION,
        True,
    )
    assert args.threshold == ROBUST_THRESHOLD
    # Explicit options win; without --robust the paper's settings stand.
    args = build_parser().parse_args(["map", "d", "--robust", "--threshold", "0.1"])
    apply_presets(args)
    assert args.threshold == 0.1
    args = build_parser().parse_args(["map", "d"])
    apply_presets(args)
    assert args.threshold == 0.36
    assert fast_config(args).baseline is False
    assert fast_config(args).zooms == ()


def test_the_parser_and_its_presets_load_no_heavy_module(tmp_path: Path) -> None:
    """``pipemap --help`` stays instant: the parser takes the presets it shows from
    :mod:`pipemap.localizer.presets` without loading numpy, OpenCV or the simulator."""
    probe = (
        "import sys\n"
        "from pipemap.cli.parser import build_parser\n"
        "build_parser().format_help()\n"
        "heavy = ('numpy', 'cv2', 'scipy', 'pybullet', 'mcap', 'rerun', 'networkx')\n"
        "print(sorted(m for m in heavy if m in sys.modules))\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], cwd=tmp_path, capture_output=True, text=True, timeout=60
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_threshold_help_says_what_decides_at_the_defaults() -> None:
    from pipemap.cli.parser import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for command in ("map", "score", "replay", "record"):
        text = " ".join(sub.choices[command].format_help().split())
        assert "two-view check decides" in text, command


def test_every_command_has_a_runner_and_every_runner_a_command() -> None:
    import importlib

    from pipemap.cli.app import COMMANDS
    from pipemap.cli.parser import build_parser

    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert sorted(COMMANDS) == sorted(sub.choices)
    for command, target in COMMANDS.items():
        module, function = target.split(":")
        assert callable(getattr(importlib.import_module(module), function)), command
