"""``--hypotheses`` on the commands that replay, in the recorder's settings, and
``score``'s count of deferred decisions (:mod:`localizer.hypotheses`)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from tests.cli.common import assert_one_error, run

STORED = Path(__file__).resolve().parents[2] / "recordings" / "random8_loops.mcap"


@pytest.mark.parametrize("command", ["score", "replay"])
def test_hypotheses_sets_the_localizers_bound(command: str) -> None:
    from pipemap.cli.localizer_options import apply_presets
    from pipemap.cli.parser import build_parser
    from pipemap.cli.replay_commands import localizer_config

    extra = ["-o", "m.json"] if command == "replay" else []
    plain = build_parser().parse_args([command, "run.mcap", *extra])
    one = build_parser().parse_args([command, "run.mcap", *extra, "--hypotheses", "1"])
    apply_presets(plain)
    apply_presets(one)
    assert localizer_config(plain).hypotheses == 8
    assert localizer_config(one).hypotheses == 1


@pytest.mark.parametrize("value", ["0", "-1", "two"])
def test_a_bad_hypotheses_gets_one_line_and_exit_2(
    value: str, capfd: pytest.CaptureFixture[str]
) -> None:
    status, out, err = run(["score", str(STORED), "--hypotheses", value], capfd)
    assert_one_error(status, out, err, "--hypotheses")


def test_a_run_with_one_hypothesis_says_so_in_its_metadata() -> None:
    from pipemap.recorder import RecordSettings
    from pipemap.sim.network import build_network

    net = build_network("paper")
    plain = RecordSettings("paper").metadata(net, "test")
    one = RecordSettings("paper", hypotheses=1).metadata(net, "test")
    assert "hypotheses" not in plain
    assert one.pop("hypotheses") == "1" and one == plain


def test_score_counts_deferred_decisions_right_wrong_and_open() -> None:
    from pipemap.replay import FileSource
    from pipemap.replay.score import score

    report = score(FileSource(STORED))
    # The stored log's junctions each look like themselves: nothing was deferred.
    assert "deferred" not in report.document(with_latency=False)
    assert report.deferred_visits == () and report.open_visits == ()
    known = [v.visit for v in report.visits if v.outcome == "correct_known"]
    new = [v.visit for v in report.visits if v.outcome == "correct_new"]
    # A deferred visit is right when it settled as the junction it is, known or new
    # (a look-alike's first visit kept apart from its twin); one taken for another
    # junction is wrong.
    wrong = tuple(
        replace(v, outcome="false_merge") if v.visit == known[2] else v for v in report.visits
    )
    flagged = replace(
        report,
        visits=wrong,
        deferred_visits=(known[0], new[1], known[2], known[1]),
        open_visits=(known[1],),
    )
    doc = flagged.document(with_latency=False)
    assert doc["deferred"] == {
        "visits": [known[0], new[1], known[2], known[1]],
        "right": 2,
        "wrong": 1,
        "open": [known[1]],
    }


def test_score_prints_the_deferred_decisions() -> None:
    from pipemap.cli.replay_commands import _report_text
    from pipemap.replay import FileSource
    from pipemap.replay.score import score

    report = score(FileSource(STORED))
    assert "deferred" not in _report_text("run.mcap", report)
    known = [v.visit for v in report.visits if v.outcome == "correct_known"]
    flagged = replace(report, deferred_visits=(known[0], known[1]), open_visits=(known[1],))
    text = _report_text("run.mcap", flagged)
    assert (
        f"deferred    2 decisions kept open among look-alikes: settled 1 right, 0 wrong, "
        f"1 still open ({known[0]}, {known[1]})"
    ) in text
