"""``pipemap experiment paper --lighting even``: the paper's evenly lit experiment."""

from __future__ import annotations

from pipemap.batch.experiment import ExperimentSettings, paper_spec, paper_spec_text
from pipemap.batch.experiment_report import _lighting_line
from pipemap.cli.experiment_command import experiment_settings
from pipemap.cli.parser import build_parser


def _settings(*flags: str) -> ExperimentSettings:
    args = build_parser().parse_args(["experiment", "paper", "--out", "x", *flags])
    settings = experiment_settings(args)
    assert isinstance(settings, ExperimentSettings)
    return settings


def test_lighting_even_lights_every_run_evenly() -> None:
    even = _settings("--lighting", "even")
    assert even.lighting == "even"
    points = paper_spec(even).points
    assert points and {p.lighting for p in points} == {"even"}
    # Every recording is recorded evenly lit: record --lighting even.
    assert all("--lighting even" in p.commands()[0] for p in points)
    assert 'lighting = ["even"]' in paper_spec_text(even)


def test_by_default_the_lamp_lights_every_run() -> None:
    lamp = _settings()
    assert lamp == ExperimentSettings()
    assert {p.lighting for p in paper_spec(lamp).points} == {"lamp"}
    # The default SPEC is experiments/paper.toml's, unchanged.
    assert "lighting" not in paper_spec_text(lamp)


def test_the_report_says_how_the_runs_were_lit() -> None:
    assert "evenly lit, as the paper's simulation was" in _lighting_line("even")
    assert "lit by the robot's lamp" in _lighting_line("lamp")
