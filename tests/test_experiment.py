"""``pipemap experiment paper``: pair statistics, the written results, the command (a
preset SPEC run by the batch machinery, each run scored by two rules)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipemap.batch.experiment import CONDITIONS, IMAGE_COUNTS, STARTS
from pipemap.batch.experiment_report import FILES
from pipemap.batch.plots import SAME, Box, box_plot
from pipemap.replay import FileSource, pair_statistics, replay, true_sweeps


def pipemap(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pipemap", *args], capture_output=True, text=True, timeout=1200
    )


def test_pairs_are_split_by_the_true_junction(recorded_run: Path) -> None:
    source = FileSource(recorded_run)
    pairs = pair_statistics(replay(source), true_sweeps(source))
    # The tour S A B A C D C F C E C A S: S twice, A three times, C four times.
    assert len(pairs.same) == 1 + 3 + 6
    assert len(pairs.different) == 13 * 12 // 2 - 10
    assert len(pairs.rotation_errors_rad) == len(pairs.same)
    assert all(0.0 <= e <= np.pi for e in pairs.rotation_errors_rad)
    assert all(-1.0 <= s <= 1.0 for s in pairs.same + pairs.different)


def test_a_box_plot_is_deterministic_and_draws_its_values() -> None:
    groups = [("a", [Box([0.2, 0.5, 0.9], SAME, "x")]), ("b", [Box([], SAME)])]
    first = box_plot(groups, "title", threshold=0.36)
    second = box_plot(groups, "title", threshold=0.36)
    assert np.array_equal(first, second)
    assert (first == np.array(SAME, np.uint8)).all(axis=2).any()
    blank = box_plot([("a", [Box([], SAME)])], "title")
    assert not (blank == np.array(SAME, np.uint8)).all(axis=2).any()


@pytest.fixture(scope="module")
def experiment(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The whole experiment at 32 px (the command as users run it, small images)."""
    out = tmp_path_factory.mktemp("experiment") / "results"
    done = pipemap("experiment", "paper", "--out", str(out), "--resolution", "32")
    assert done.returncode == 0, done.stderr
    # 19 recordings, each scored by the paper's rule and pipemap's defaults.
    assert "[38/38]" in done.stderr and "starts" in done.stdout
    return out


def test_the_experiment_writes_every_table_and_figure(experiment: Path) -> None:
    for name in FILES:
        assert (experiment / name).stat().st_size > 0, name
    doc = json.loads((experiment / "experiment.json").read_text())
    assert doc["settings"] == {
        "resolution_px": 32,
        "seed": 0,
        "threshold": 0.36,
        "lighting": "lamp",
    }
    assert doc["rules"]["paper"]["flags"] == ["--rule", "paper"]
    assert doc["rules"]["default"]["flags"] == []
    assert set(doc["conditions"]) == {"paper", "aligned"}
    for runs in doc["conditions"].values():
        assert list(runs) == list(CONDITIONS)
        for run in runs.values():
            assert list(run["rules"]) == ["paper", "default"]
            assert {r["visits"] for r in run["rules"].values()} == {13}
            assert run["pairs"]["same"]["n"] == 10 and run["pairs"]["different"]["n"] == 68
    assert [int(n) for n in doc["images"]] == list(IMAGE_COUNTS)
    assert [r["images_per_sweep"] for r in doc["images"].values()] == list(IMAGE_COUNTS)
    assert list(doc["starts"]) == list(STARTS)
    assert [r["start"] for r in doc["starts"].values()] == list(STARTS)
    assert doc["paper"]["threshold"] == 0.36
    text = (experiment / "experiment.md").read_text()
    for heading in ("Table 1", "Table 2", "Figure 6", "Figure 7", "every start"):
        assert heading in text
    assert "0.700 ± 0.157" in text  # the paper's numbers, beside ours
    # Every table of decisions names its rule, both side by side.
    assert "`pipemap score --rule paper`" in text
    assert "`pipemap score` (no flags)" in text
    assert text.count("| paper's rule: right |") == 3  # decisions, Figure 6, starts
    assert "| pipemap's defaults: right | pipemap's defaults: false merges |" in text
    assert "pipemap's defaults: right | pipemap's defaults: map |" in text
    assert "Map correct from" in text
    assert "exits with its own range sensors" in text
    # The batch's own files: the run folders and the table.
    with (experiment / "results.csv").open() as f:
        assert sum(1 for _ in f) == 1 + 38
    for name in ("figure6_images.png", "figure7_similarity.png"):
        image = cv2.imread(str(experiment / name))
        assert image is not None and image.shape[2] == 3


def test_the_experiment_refuses_to_replace_results(experiment: Path) -> None:
    done = pipemap("experiment", "paper", "--out", str(experiment))
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "--force" in done.stderr


def test_the_experiment_resumes_without_running_again(experiment: Path) -> None:
    before = (experiment / "experiment.json").read_text()
    done = pipemap(
        "experiment", "paper", "--out", str(experiment), "--resolution", "32", "--resume"
    )
    assert done.returncode == 0, done.stderr
    assert "0 runs to make" in done.stderr and "38 complete runs kept" in done.stderr
    after = json.loads((experiment / "experiment.json").read_text())
    assert after["conditions"] == json.loads(before)["conditions"]


def test_the_experiment_resumes_only_at_its_own_settings(experiment: Path) -> None:
    files = ("results.csv", "results.json", "spec.toml", "experiment.md")
    before = {name: (experiment / name).read_bytes() for name in files}
    done = pipemap("experiment", "paper", "--out", str(experiment), "--resume")
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "resolution (32 there; 400 here)" in done.stderr
    assert {name: (experiment / name).read_bytes() for name in files} == before


@pytest.mark.parametrize(
    "args,message",
    [
        (["experiment", "nature", "--out", "x"], "invalid choice"),
        (["experiment", "paper"], "--out"),
        (["experiment", "paper", "--out", "{tmp}/no/such/folder/x"], "does not exist"),
        (["experiment", "paper", "--out", "x", "--resolution", "8"], "resolution"),
    ],
)
def test_bad_experiment_arguments_get_one_line(
    args: list[str], message: str, tmp_path: Path
) -> None:
    # A folder of our own that does not exist (the machine is shared: /no/such may).
    done = pipemap(*(a.format(tmp=tmp_path) for a in args))
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and message in done.stderr
