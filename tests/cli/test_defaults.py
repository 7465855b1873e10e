"""Every default of a run is written once (:mod:`pipemap.defaults`): what a command's
flags give when none is set is what the library's settings give when none is passed.
A parser, a batch key or a dataclass that writes its own default fails here once that
default and the library's part."""

from __future__ import annotations

import dataclasses

from pipemap import defaults
from pipemap.cli.parser import build_parser
from pipemap.cli.run_settings import record_settings
from pipemap.recorder import RecordSettings
from pipemap.sim.controller import ExplorerConfig
from pipemap.sim.episode import Condition, SimConfig
from pipemap.sim.world import CameraSpec


def _parsed(*argv: str) -> RecordSettings:
    return record_settings(build_parser().parse_args(list(argv)))


def test_record_without_flags_runs_the_library_defaults() -> None:
    assert _parsed("record", "--network", "paper", "-o", "run.mcap") == RecordSettings("paper")


def test_sim_without_flags_runs_the_library_defaults() -> None:
    parsed = _parsed("sim", "--network", "paper", "--save-sweeps", "out")
    assert parsed == RecordSettings("paper", condition=Condition.PERFECT)


def test_a_batch_key_left_out_takes_the_library_default() -> None:
    from pipemap.batch.spec import parse_spec

    spec = parse_spec('[grid]\nnetwork = ["paper"]\n')
    (point,) = spec.points
    # The batch resolves the start to the network's entry; the library leaves it None.
    settings = dataclasses.replace(point.record_settings(), start=None)
    assert settings == RecordSettings("paper")
    assert point.threshold == RecordSettings("paper").threshold


def test_experiment_flags_default_to_the_library() -> None:
    args = build_parser().parse_args(["experiment", "paper", "--out", "exp"])
    library = RecordSettings("paper")
    assert (args.resolution, args.seed, args.threshold) == (
        library.resolution_px,
        library.seed,
        library.threshold,
    )


def test_the_simulator_dataclasses_share_the_defaults() -> None:
    settings = RecordSettings("paper")
    assert CameraSpec() == settings.camera()
    assert CameraSpec().resolution_px == defaults.RESOLUTION_PX
    assert ExplorerConfig() == settings.explorer_config()
    assert SimConfig().images_per_sweep == settings.images_per_sweep == defaults.IMAGES_PER_SWEEP
    assert settings.lamp_strength == defaults.LAMP_STRENGTHS[defaults.LIGHTING]
    assert (settings.image_format, settings.jpeg_quality) == (
        defaults.IMAGE_FORMAT,
        defaults.JPEG_QUALITY,
    )
