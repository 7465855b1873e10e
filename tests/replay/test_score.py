"""Scoring: outcomes, map correctness, and the score command's outputs."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from pipemap.localizer import PHASES
from pipemap.recorder import METADATA_RUN, LogWriter, read_log
from pipemap.replay.score import _map_correct


def pipemap(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args], capture_output=True, text=True, timeout=300
    )


@pytest.mark.parametrize(
    "predicted,true,correct",
    [
        ([0, 1, 0, 2, 0], list("SASBA"), False),  # the last visit is A, not S
        ([0, 1, 2, 1, 3], list("SABAC"), True),
        ([0, 1, 2, 1, 0], list("SABAS"), True),
        ([0, 1, 2, 1, 2], list("SABAC"), False),  # C merged into B
        ([0, 1, 2, 3, 4], list("SABAC"), False),  # A's revisit made a duplicate
        ([5, 7, 6, 7, 9], list("SABAC"), True),  # the ids need not be 0..n
    ],
)
def test_map_correct_needs_one_map_node_per_true_node(
    predicted: list[int], true: list[str], correct: bool
) -> None:
    assert _map_correct(predicted, true) is correct


def test_score_reports_every_visit_against_the_truth(recorded_run: Path, tmp_path: Path) -> None:
    results = tmp_path / "results"
    done = pipemap("score", str(recorded_run), "--json", "--save-results", str(results))
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    assert [v["true_node"] for v in doc["per_visit"]] == list("SABACDCFCECAS")
    assert sum(doc["decisions"].values()) == doc["visits"] == 13
    assert doc["true_nodes"] == 7
    for key in ("known", "unknown"):
        assert set(doc["similarity"][key]) == {"mean", "std", "n"}
    # Visits 1 and 2 had nothing to compare with (visit 2 cannot be S, which it left).
    assert doc["similarity"]["known"]["n"] + doc["similarity"]["unknown"]["n"] == 11
    assert [v["candidate"] for v in doc["per_visit"][:2]] == [None, None]
    assert set(doc["rotation_error_rad"]["known"]) == {"mean", "max", "n"}
    latency = doc["latency_ms"]
    assert latency["max"] >= latency["p95"] >= latency["median"] > 0
    assert latency["max"] >= latency["mean"] > 0
    # Where the mean goes: every phase timed, none longer than the whole.
    phases = latency["phases"]
    assert list(phases) == list(PHASES)
    assert all(t >= 0.0 for t in phases.values())
    assert phases["ncc"] > 0 and phases["keypoints"] > 0
    assert sum(phases.values()) <= latency["mean"] + 1e-3 * len(phases)
    saved = json.loads((results / "score.json").read_text())
    assert saved["decisions"] == doc["decisions"]
    rows = list(csv.DictReader((results / "visits.csv").open()))
    assert [r["true_node"] for r in rows] == list("SABACDCFCECAS")
    for r in rows:  # each visit's phases, within its latency
        timed = [float(r[f"{p}_ms"]) for p in PHASES]
        assert min(timed) >= 0.0 and sum(timed) <= float(r["latency_ms"]) + 1e-3 * len(timed)
    # Correct known visits have a rotation error: within two pixels at 32 px (one
    # pixel is 80/32 degrees, 0.044 rad).
    for v in doc["per_visit"]:
        if v["outcome"] == "correct_known":
            assert abs(v["rotation_error_rad"]) < 2 * 0.0437


def test_without_the_two_view_check_no_time_goes_to_keypoints(recorded_run: Path) -> None:
    done = pipemap("score", str(recorded_run), "--json", "--no-two-view")
    assert done.returncode == 0, done.stderr
    phases = json.loads(done.stdout)["latency_ms"]["phases"]
    assert phases["keypoints"] == 0.0 and phases["ncc"] > 0


def test_a_wrong_map_is_a_result_not_an_error(recorded_run: Path) -> None:
    paper = (
        "--threshold",
        "-1",
        "--no-verify",
        "--allow-repeat",
        "--no-port-check",
        "--no-odometry-check",
    )
    done = pipemap("score", str(recorded_run), "--json", *paper)
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    assert doc["map_correct"] is False
    # Every visit is taken for the first junction, S: right only for the return to S.
    assert doc["decisions"] == {
        "correct_known": 1,
        "correct_new": 1,
        "false_merge": 11,
        "false_new": 0,
    }
    text = pipemap("score", str(recorded_run), *paper)
    assert text.returncode == 0 and "WRONG" in text.stdout
    assert ", 11 false merges, 0 false new" in text.stdout


def test_score_text_formats(recorded_run: Path) -> None:
    """One merge is a merge; milliseconds to 0.1, similarities to 0.001, radians to 1e-4."""
    import re

    text = pipemap("score", str(recorded_run), "--threshold", "0.1", "--no-verify").stdout
    doc = json.loads(
        pipemap("score", str(recorded_run), "--threshold", "0.1", "--no-verify", "--json").stdout
    )
    merges = doc["decisions"]["false_merge"]
    assert f", {merges} false merge{'' if merges == 1 else 's'}," in text
    assert re.search(
        r"latency     mean \d+\.\d ms, median \d+\.\d, 95th percentile \d+\.\d, "
        r"max \d+\.\d ms per decision",
        text,
    )
    assert re.search(
        r"of the mean: ncc \d+\.\d, keypoints \d+\.\d, check \d+\.\d, map \d+\.\d ms", text
    )
    rows = [line.split() for line in text.splitlines() if line.startswith("0001")]
    assert rows and rows[0][4:6] == ["-", "-"]  # the first visit compared with nothing
    second_known = next(v for v in doc["per_visit"] if v["similarity"] is not None)
    row = next(line.split() for line in text.splitlines() if line.startswith(second_known["visit"]))
    assert row[4] == f"{second_known['similarity']:.3f}"


def test_score_illumination_follows_the_log_unless_told(recorded_run: Path) -> None:
    def scored(*flags: str) -> tuple[list[float], object]:
        done = pipemap("score", str(recorded_run), "--json", *flags)
        assert done.returncode == 0, done.stderr
        doc = json.loads(done.stdout)
        return [v["similarity"] for v in doc["per_visit"]], doc["pairs"]

    auto = scored()
    assert auto == scored("--illumination", "lamp")  # the log's camera had its lamp on
    even = scored("--illumination", "even")
    # Decisions and the pair statistics (Table 1) both see the sets as the localizer does.
    assert auto[0] != even[0] and auto[1] != even[1]
    bad = pipemap("score", str(recorded_run), "--illumination", "dim")
    assert bad.returncode == 2 and "--illumination" in bad.stderr


def test_score_needs_the_truth(recorded_run: Path, tmp_path: Path) -> None:
    contents = read_log(recorded_run)
    blind = tmp_path / "blind.mcap"
    with blind.open("wb") as f, LogWriter(f, contents.metadata[METADATA_RUN]) as writer:
        for m in contents.messages:
            if m.topic.startswith("/robot/"):
                writer.write_serialized(m.topic, m.log_time_ns, m.data)
    done = pipemap("score", str(blind))
    assert done.returncode == 2 and "no ground truth" in done.stderr


@pytest.mark.parametrize(
    ("latencies", "expected"),
    [
        # 1..20 ms: the 95th percentile lies 0.95 of the way from the first to the
        # last, at 18.05 positions: 19 + 0.05.
        (
            [float(x) for x in range(20, 0, -1)],
            {"mean": 10.5, "median": 10.5, "p95": 19.05, "max": 20.0},
        ),
        # One slow decision among nine quick ones: the mean hides it, the tail shows it.
        ([5.0] * 9 + [300.0], {"mean": 34.5, "median": 5.0, "p95": 167.25, "max": 300.0}),
        ([7.25], {"mean": 7.25, "median": 7.25, "p95": 7.25, "max": 7.25}),
        ([], {"mean": None, "median": None, "p95": None, "max": None}),
    ],
)
def test_the_latency_summary_gives_the_tail_as_well_as_the_mean(
    latencies: list[float], expected: dict[str, float | None]
) -> None:
    from pipemap.replay.score import latency_summary

    assert latency_summary(latencies) == expected
