"""Runs in worlds whose junctions look alike, end to end: ``record --alike``, the
log's simulator settings, ``score``'s report of the shared looks, and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pipemap.recorder import METADATA_RUN, read_log
from tests.cli.common import assert_one_error, run

#: The paper's network at alike 1: the entry and its four dead ends wear one look.
ALIKE = ["S", "B", "D", "E", "F"]


@pytest.fixture(scope="module")
def alike_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("alike") / "run.mcap"
    from pipemap.recorder import RecordSettings, record_run
    from pipemap.sim.network import build_network

    settings = RecordSettings("paper", resolution_px=64, alike=1.0)
    record_run(path, settings, build_network("paper"), "test")
    return path


def test_the_log_names_the_fraction_and_the_junctions_that_share_a_look(
    alike_run: Path,
) -> None:
    run_meta = read_log(alike_run).metadata[METADATA_RUN]
    simulator = json.loads(run_meta["simulator"])
    assert simulator["alike"]["fraction"] == 1.0
    assert [sorted(g) for g in simulator["alike"]["groups"]] == [sorted(ALIKE)]


def test_score_reports_which_true_junctions_share_a_look(
    alike_run: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    status, out, err = run(["score", str(alike_run), "--json"], capfd)
    assert status == 0, err
    doc = json.loads(out)
    assert [sorted(g) for g in doc["look_alike"]] == [sorted(ALIKE)]
    status, out, err = run(["score", str(alike_run)], capfd)
    line = next(t for t in out.splitlines() if t.startswith("look-alike"))
    assert "5 junctions share 1 looks" in line
    assert all(label in line for label in ALIKE)


def test_a_log_without_alike_reports_no_shared_look(
    capfd: pytest.CaptureFixture[str],
) -> None:
    stored = Path(__file__).resolve().parents[2] / "recordings" / "random8_loops.mcap"
    status, out, _ = run(["score", str(stored), "--json"], capfd)
    assert status == 0 and "look_alike" not in json.loads(out)
    assert "alike" not in json.loads(read_log(stored).metadata[METADATA_RUN]["simulator"])


@pytest.mark.parametrize("command", ["record", "sim"])
@pytest.mark.parametrize("value", ["1.5", "-0.1", "nan", "half"])
def test_a_bad_alike_gets_one_line_and_exit_2(
    command: str, value: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    out_flag = ["-o", str(tmp_path / "run.mcap")] if command == "record" else []
    out_flag = out_flag or ["--save-sweeps", str(tmp_path / "sweeps")]
    status, out, err = run([command, "--network", "paper", "--alike", value, *out_flag], capfd)
    assert_one_error(status, out, err, "--alike")
    assert list(tmp_path.iterdir()) == []


def test_no_odometry_check_turns_the_localizers_check_off() -> None:
    from pipemap.cli.localizer_options import apply_presets
    from pipemap.cli.parser import build_parser
    from pipemap.cli.replay_commands import localizer_config

    for command in ("score", "replay"):
        extra = ["-o", "m.json"] if command == "replay" else []
        plain = build_parser().parse_args([command, "run.mcap", *extra])
        off = build_parser().parse_args([command, "run.mcap", *extra, "--no-odometry-check"])
        apply_presets(plain)
        apply_presets(off)
        assert localizer_config(plain).odometry_check
        assert not localizer_config(off).odometry_check


def test_score_counts_the_decisions_made_among_junctions_nothing_told_apart() -> None:
    from dataclasses import replace

    from pipemap.replay import FileSource
    from pipemap.replay.score import score

    stored = Path(__file__).resolve().parents[2] / "recordings" / "random8_loops.mcap"
    report = score(FileSource(stored))
    assert "undecided" not in report.document(with_latency=False)
    known = [v.visit for v in report.visits if v.outcome == "correct_known"]
    new = [v.visit for v in report.visits if v.outcome == "correct_new"]
    # Right as the final map has it, known or new (a visit recognised among alike
    # junctions may settle as a new one); one taken for another junction is wrong.
    visits = tuple(
        replace(v, outcome="false_merge") if v.visit == known[1] else v for v in report.visits
    )
    flagged = replace(report, visits=visits, alike_visits=(known[0], new[1], known[1]))
    doc = flagged.document(with_latency=False)
    assert doc["undecided"] == {"visits": [known[0], new[1], known[1]], "right": 2, "wrong": 1}


def test_a_run_without_the_odometry_check_says_so_in_its_metadata() -> None:
    from pipemap.recorder import RecordSettings
    from pipemap.sim.network import build_network

    net = build_network("paper")
    plain = RecordSettings("paper").metadata(net, "test")
    off = RecordSettings("paper", odometry_check=False).metadata(net, "test")
    assert "odometry_check" not in plain
    assert off.pop("odometry_check") == "false" and off == plain


def test_sim_draws_the_look_alike_world(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    # The entry S wears the dead ends' shared look at --alike 1: its sweep changes;
    # at --alike 0 the sweep is the one of a run without the flag.
    sweeps = {}
    for name, extra in (("plain", []), ("zero", ["--alike", "0"]), ("one", ["--alike", "1"])):
        out = tmp_path / name
        argv = ["sim", "--network", "paper", "--resolution", "16", "--save-sweeps", str(out)]
        status, _, err = run([*argv, *extra], capfd)
        assert status == 0, err
        sweeps[name] = [(out / "0001" / f"camera_image{k}.png").read_bytes() for k in (1, 2, 3)]
    assert sweeps["zero"] == sweeps["plain"]
    assert sweeps["one"] != sweeps["plain"]
