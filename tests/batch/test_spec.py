"""SPEC validation: every mistake is one line of ``pipemap batch``, exit 2, before any
run starts (nothing is written, Ray is not started)."""

from __future__ import annotations

import math
import socket
import tomllib
from dataclasses import replace
from pathlib import Path

import pytest

from pipemap.batch import GRID_KEYS, RULES, SpecError, load_spec, parse_spec
from pipemap.batch.experiment import ExperimentSettings, paper_spec, paper_spec_text
from pipemap.batch.spec import RunPoint
from pipemap.cli.app import main
from pipemap.cli.localizer_options import apply_presets
from pipemap.cli.parser import build_parser
from pipemap.cli.replay_commands import localizer_config
from pipemap.localizer import PAPER, LocalizerConfig

REPO = Path(__file__).resolve().parents[2]

SMALL = """
[grid]
network = ["paper", "random:8"]
seed = [0, 1]
resolution = [32]
rule = ["default", "paper"]
"""


def test_the_grid_is_the_cartesian_product_with_record_defaults() -> None:
    spec = parse_spec(SMALL)
    assert len(spec.points) == 8 and spec.recordings() == 4
    first = spec.points[0]
    assert first == RunPoint(
        "paper",
        0,
        "S",
        "autonomous",
        32,
        6,
        True,
        "map",
        0,
        0,
        0.0,
        "lamp",
        0.0,
        1.0,
        "default",
        0.36,
    )
    # network outermost, the scoring keys innermost: a recording's runs are neighbours
    assert [p.rule for p in spec.points[:2]] == ["default", "paper"]
    assert [(p.network, p.seed) for p in spec.points[::2]] == [
        ("paper", 0),
        ("paper", 1),
        ("random:8", 0),
        ("random:8", 1),
    ]
    assert spec.varying == ("network", "seed", "rule")
    assert len({p.run_id for p in spec.points}) == 8


def test_an_empty_grid_is_one_run_at_the_defaults() -> None:
    (point,) = parse_spec("[grid]\n").points
    assert point.settings() == {
        "network": "paper",
        "seed": 0,
        "start": "S",
        "condition": "autonomous",
        "resolution": 400,
        "images": 6,
        "align_sweeps": True,
        "explore": "map",
        "obstacles": 0,
        "motor_faults": 0,
        "tilt_deg": 0.0,
        "lighting": "lamp",
        "alike": 0.0,
        "odometry_drift": 1.0,
        "rule": "default",
        "threshold": 0.36,
    }
    assert list(point.settings()) == list(GRID_KEYS)


def test_run_ids_are_stable_names_of_the_settings() -> None:
    point = RunPoint(
        "random:8",
        3,
        "n2",
        "noise",
        64,
        9,
        False,
        "map",
        0,
        0,
        0.0,
        "lamp",
        0.0,
        1.0,
        "no-verify",
        0.33,
    )
    # Real conditions at their defaults leave the name as it was before they were keys.
    assert point.run_id == "random8-seed3-n2-noise-64px-9img-straight-map-no-verify-t0.33"
    real = RunPoint(
        "paper",
        0,
        "S",
        "autonomous",
        64,
        6,
        True,
        "map",
        3,
        2,
        2.5,
        "even",
        0.0,
        1.0,
        "paper",
        0.36,
    )
    assert (
        real.run_id
        == "paper-seed0-S-autonomous-64px-6img-aligned-map-obs3-motor2-tilt2.5-even-paper-t0.36"
    )
    # The default start is the entry, named: leaving it out or naming it is one run.
    named = parse_spec('[grid]\nstart = ["S"]\n').points[0]
    assert named.run_id == parse_spec("[grid]\n").points[0].run_id


def test_explore_is_a_recording_setting_handed_to_record() -> None:
    from pipemap.recorder import Explore

    spec = parse_spec('[grid]\nexplore = ["map", "right-hand"]\n')
    assert [p.explore for p in spec.points] == ["map", "right-hand"]
    assert spec.recordings() == 2  # a different walk: a different recording
    assert [p.record_settings().explore for p in spec.points] == [Explore.MAP, Explore.RIGHT_HAND]
    assert "--explore right-hand" in spec.points[1].commands()[0]
    with pytest.raises(SpecError, match="unknown exploration 'left-hand'"):
        parse_spec('[grid]\nexplore = ["left-hand"]\n')


def test_real_conditions_are_recording_settings_handed_to_record() -> None:
    spec = parse_spec(
        "[grid]\nobstacles = [0, 2]\nmotor_faults = [0, 1]\ntilt_deg = [0, 3]\n"
        'lighting = ["lamp", "even"]\n'
    )
    assert spec.recordings() == 16 and len(spec.points) == 16
    assert spec.varying == ("obstacles", "motor_faults", "tilt_deg", "lighting")
    last = spec.points[-1]
    settings = last.record_settings()
    assert (settings.obstacles, settings.motor_faults, settings.lamp_strength) == (2, 1, 0.0)
    assert settings.tilt_rad == pytest.approx(math.radians(3.0))
    assert spec.points[0].record_settings().lamp_strength == 1.0
    assert last.commands()[0].endswith(
        "--obstacles 2 --motor-faults 1 --tilt-deg 3 --lighting even -o run.mcap"
    )
    assert "--obstacles" not in spec.points[0].commands()[0]


def test_alike_is_a_recording_setting_handed_to_record() -> None:
    spec = parse_spec('[grid]\nalike = [0, 0.5, 1]\nrule = ["default", "paper"]\n')
    assert spec.recordings() == 3 and len(spec.points) == 6
    assert spec.varying == ("alike", "rule")
    half, full = spec.points[2], spec.points[4]
    assert half.record_settings().alike == 0.5 and full.record_settings().alike == 1.0
    assert spec.points[0].record_settings().alike == 0.0
    assert half.commands()[0].endswith("--alike 0.5 -o run.mcap")
    assert "--alike" not in spec.points[0].commands()[0]
    assert "alike" not in spec.points[0].run_id and "alike0.5" in half.run_id


def test_odometry_drift_is_a_recording_setting_handed_to_record() -> None:
    spec = parse_spec('[grid]\nodometry_drift = [1, 10]\nrule = ["default", "paper"]\n')
    assert spec.recordings() == 2 and len(spec.points) == 4
    assert spec.varying == ("odometry_drift", "rule")
    plain, poor = spec.points[0], spec.points[2]
    assert plain.record_settings().odometry_drift == 1.0
    assert poor.record_settings().odometry_drift == 10.0
    assert poor.commands()[0].endswith("--odometry-drift 10 -o run.mcap")
    assert "--odometry-drift" not in plain.commands()[0]
    assert "drift" not in plain.run_id and poor.run_id.endswith("-drift10.0-default-t0.36")


def test_grids_are_joined_and_shared_runs_made_once() -> None:
    spec = parse_spec("[[grid]]\nseed = [0, 1]\n[[grid]]\nseed = [1, 2]\n")
    assert [p.seed for p in spec.points] == [0, 1, 2]


def test_the_commands_rebuild_the_run() -> None:
    point = RunPoint(
        "grid:3x3",
        1,
        "S",
        "perfect",
        96,
        6,
        False,
        "map",
        0,
        0,
        0.0,
        "lamp",
        0.0,
        1.0,
        "paper",
        0.36,
    )
    record, score = point.commands()
    assert record == (
        "pipemap record --network grid:3x3 --seed 1 --start S --condition perfect "
        "--resolution 96 --images 6 --no-align-sweeps --explore map -o run.mcap"
    )
    assert score == "pipemap score --rule paper run.mcap --threshold 0.36 --json"


@pytest.mark.parametrize("rule", list(RULES))
def test_each_rule_is_its_pipemap_score_flags(rule: str) -> None:
    """A rule's localizer is the one ``pipemap score FLAGS`` builds."""
    args = build_parser().parse_args(["score", "x.mcap", *RULES[rule].flags])
    apply_presets(args)
    assert localizer_config(args) == RULES[rule].config(0.36)
    args = build_parser().parse_args(["score", "x.mcap", *RULES[rule].flags, "--threshold", "0.3"])
    apply_presets(args)
    assert localizer_config(args) == RULES[rule].config(0.3)


def test_the_example_specs_are_valid() -> None:
    examples = sorted((REPO / "experiments").glob("*.toml"))
    assert len(examples) >= 2
    for path in examples:
        assert load_spec(path).points, path


def test_experiments_paper_toml_is_the_presets_spec() -> None:
    text = (REPO / "experiments" / "paper.toml").read_text()
    assert text == paper_spec_text()
    spec = paper_spec()
    assert len(spec.points) == 38 and spec.recordings() == 19
    assert {p.rule for p in spec.points} == {"paper", "default"}
    small = paper_spec(ExperimentSettings(resolution_px=32, seed=4, threshold=0.3))
    assert {(p.resolution, p.seed, p.threshold) for p in small.points} == {(32, 4, 0.3)}


# ------------------------------------------------------------ one line per mistake


def cli(*args: str) -> tuple[int, list[str]]:
    """``pipemap ARGS`` in this process: its exit status and its lines of stderr."""
    import contextlib
    import io

    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        try:
            code = main(list(args))
        except SystemExit as exc:  # argparse
            code = int(exc.code or 0)
    return code, err.getvalue().splitlines()


BAD_SPECS = [
    pytest.param("[grid\nseed = [0]\n", "not valid TOML", id="malformed-toml"),
    pytest.param('description = "x"\n', "no [grid] table", id="no-grid"),
    pytest.param("seed = [0]\n", "seed: grid keys go under the [grid] heading", id="stray-key"),
    pytest.param(
        '[grid]\nnetwork = ["paper"]\n[extra]\n', "unknown top-level key 'extra'", id="top"
    ),
    pytest.param("description = 3\n[grid]\n", "description must be a string", id="description"),
    pytest.param("grid = []\n", "[[grid]] is empty", id="empty-grids"),
    pytest.param("[grid]\nseeds = [0]\n", "unknown key 'seeds'", id="unknown-key"),
    pytest.param("[grid]\nseed = 0\n", "seed: must be a list", id="not-a-list"),
    pytest.param("[grid]\nseed = []\n", "seed: empty list", id="empty-list"),
    pytest.param('[grid]\nnetwork = ["maze:3"]\n', "unknown network spec 'maze:3'", id="network"),
    pytest.param('[grid]\nnetwork = ["grid:1x3"]\n', "at least 2 rows", id="network-size"),
    pytest.param('[grid]\ncondition = ["windy"]\n', "unknown condition 'windy'", id="condition"),
    pytest.param('[grid]\nrule = ["robust"]\n', "unknown rule 'robust'", id="rule"),
    pytest.param("[grid]\nseed = [-1]\n", "seed: -1 is not a whole number", id="seed"),
    pytest.param("[grid]\nresolution = [8]\n", "resolution: 8 is not", id="resolution"),
    pytest.param("[grid]\nimages = [1.5]\n", "images: 1.5 is not", id="images"),
    pytest.param(
        "[grid]\nthreshold = [2.0]\n", "threshold: 2.0 is not a threshold", id="threshold"
    ),
    pytest.param('[grid]\nalign_sweeps = ["yes"]\n', "'yes' is not true or false", id="align"),
    pytest.param("[grid]\nnetwork = [3]\n", "network: 3 is not a name", id="network-type"),
    pytest.param("[grid]\nseed = [0, 0]\n", "seed: 0 is listed twice", id="duplicate"),
    pytest.param('[grid]\nlighting = ["dim"]\n', "unknown lighting 'dim'", id="lighting"),
    pytest.param("[grid]\ntilt_deg = [16]\n", "tilt_deg: 16 is not a tilt in [0, 15]", id="tilt"),
    pytest.param("[grid]\nobstacles = [-1]\n", "obstacles: -1 is not a whole number", id="obs"),
    pytest.param("[grid]\nalike = [1.5]\n", "alike: 1.5 is not a fraction in [0, 1]", id="alike"),
    pytest.param(
        "[grid]\nodometry_drift = [0.5]\n",
        "odometry_drift: 0.5 is not a drift factor in [1, 10]",
        id="odometry_drift",
    ),
    pytest.param(
        '[grid]\ncondition = ["perfect"]\nobstacles = [1]\n',
        "obstacles: 1 with condition 'perfect': only the autonomous robot",
        id="obstacles-placed",
    ),
    pytest.param(
        '[grid]\ncondition = ["noise"]\nmotor_faults = [2]\n',
        "motor_faults: 2 with condition 'noise': only the autonomous robot",
        id="motor-faults-placed",
    ),
    pytest.param("[grid]\nmotor_faults = [1.5]\n", "motor_faults: 1.5 is not", id="motor"),
    pytest.param(
        '[grid]\nnetwork = ["grid:2x2"]\nobstacles = [9]\n',
        "obstacles: 9 in grid:2x2 (seed 0): 9 obstacles: the network has only",
        id="obstacles-too-many",
    ),
    pytest.param(
        '[grid]\nnetwork = ["paper", "grid:2x2"]\nstart = ["A"]\n',
        "start 'A': no such node in grid:2x2",
        id="start",
    ),
]


@pytest.mark.parametrize(("text", "message"), BAD_SPECS)
def test_a_bad_spec_gets_one_line_and_exit_2(tmp_path: Path, text: str, message: str) -> None:
    spec = tmp_path / "spec.toml"
    spec.write_text(text)
    out = tmp_path / "out"
    code, lines = cli("batch", str(spec), "--out", str(out))
    assert code == 2
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"pipemap: error: {spec}: ") and message in lines[0], lines
    assert not out.exists()  # before any run


def test_every_mistake_of_a_spec_is_its_own_line(tmp_path: Path) -> None:
    spec = tmp_path / "spec.toml"
    spec.write_text(
        '[grid]\nseed = []\ncondition = ["windy"]\nrule = ["x", "paper"]\ncolour = [1]\n'
    )
    code, lines = cli("batch", str(spec), "--out", str(tmp_path / "out"))
    assert code == 2 and len(lines) == 4, lines
    assert all(line.startswith("pipemap: error: ") for line in lines)
    with pytest.raises(SpecError) as caught:
        parse_spec(spec.read_text())
    assert len(caught.value.mistakes) == 4


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def spec_file(tmp_path: Path) -> Path:
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    return path


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--address", "localhost"], "expected HOST:PORT"),
        (["--address", "127.0.0.1:99999"], "expected HOST:PORT"),
        (["--address", f"127.0.0.1:{_free_port()}"], "no Ray head answers there"),
        (["--workers", "0"], "must be at least 1"),
        (["--resume", "--force"], "not allowed with argument"),
    ],
    ids=["address-form", "address-port", "address-unreachable", "workers", "resume-force"],
)
def test_bad_batch_options_get_one_line(
    spec_file: Path, tmp_path: Path, extra: list[str], message: str
) -> None:
    out = tmp_path / "out"
    code, lines = cli("batch", str(spec_file), "--out", str(out), *extra)
    assert code == 2 and len(lines) == 1, lines
    assert lines[0].startswith("pipemap: error: ") and message in lines[0], lines
    assert not out.exists()


def test_the_output_folder_is_checked_before_any_run(spec_file: Path, tmp_path: Path) -> None:
    cases = []
    a_file = tmp_path / "file"
    a_file.write_text("x")
    cases.append((a_file, "is a file, not a folder"))
    cases.append((tmp_path / "no" / "out", "does not exist"))
    earlier = tmp_path / "earlier"
    earlier.mkdir()
    (earlier / "results.csv").write_text("x")
    cases.append((earlier, "without --resume"))
    for out, message in cases:
        code, lines = cli("batch", str(spec_file), "--out", str(out))
        assert code == 2 and len(lines) == 1, lines
        assert message in lines[0], lines
    assert (earlier / "results.csv").read_text() == "x"  # untouched


def test_a_missing_spec_gets_one_line(tmp_path: Path) -> None:
    code, lines = cli("batch", str(tmp_path / "none.toml"), "--out", str(tmp_path / "out"))
    assert code == 2 and lines == [f"pipemap: error: SPEC {tmp_path / 'none.toml'}: no such file"]


def test_a_spec_that_parses_is_valid_toml() -> None:
    """The doc's example SPEC parses as it stands."""
    text = (REPO / "docs" / "batch.md").read_text()
    block = text.split("```toml\n", 1)[1].split("```", 1)[0]
    tomllib.loads(block)
    assert parse_spec(block).points


@pytest.mark.parametrize("command", ["replay", "score", "view"])
def test_the_paper_rule_is_one_rule_on_the_command_line_in_batches_and_the_api(
    command: str,
) -> None:
    args = build_parser().parse_args([command, "x.mcap", "--rule", "paper"])
    apply_presets(args)
    assert localizer_config(args) == RULES["paper"].config(0.36) == PAPER
    args = build_parser().parse_args([command, "x.mcap", "--rule", "paper", "--threshold", "0.5"])
    apply_presets(args)
    assert localizer_config(args) == RULES["paper"].config(0.5) == replace(PAPER, threshold=0.5)
    assert RULES["paper"].flags == ("--rule", "paper")


def test_map_takes_the_paper_rule(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """``pipemap map --rule paper`` hands :data:`PAPER` to ``api.map_image_sets``."""
    from pipemap.cli import folder_commands

    given = []

    def map_image_sets(dirs: list[str], config: object, *rest: object) -> dict[str, list[str]]:
        given.append(config)
        return {"visits": [], "edges": [], "nodes": []}

    monkeypatch.setattr(folder_commands.api, "map_image_sets", map_image_sets)
    for flags in (["--rule", "paper"], []):
        assert main(["map", str(tmp_path), *flags]) == 0
    assert given == [PAPER, LocalizerConfig()]
