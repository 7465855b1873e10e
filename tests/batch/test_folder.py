"""``--resume`` continues the batch a folder holds, never another one: a SPEC (or an
experiment's settings) that makes other runs is refused, exit 2, in one line naming
each key that differs, before anything is written (Ray is not started here)."""

from __future__ import annotations

from pathlib import Path

import pytest

from pipemap.batch import parse_spec
from pipemap.batch.experiment import ExperimentSettings, paper_spec_text
from pipemap.batch.folder import spec_differences
from tests.batch.test_spec import SMALL, cli

#: A results table as a batch leaves it: the tests check that a refusal leaves it be.
TABLE = "run_id,network\nrun-a,paper\nrun-b,random:8\n"


def test_a_spec_reformatted_or_recommented_makes_the_same_runs() -> None:
    other = "# the same grid, other words\n" + SMALL.replace(", ", ",  ")
    assert spec_differences(parse_spec(SMALL), parse_spec(other)) == []


def test_each_differing_key_is_named_with_its_values() -> None:
    other = SMALL.replace("seed = [0, 1]", "seed = [0, 2]").replace("[32]", "[64]")
    differences = spec_differences(parse_spec(SMALL), parse_spec(other))
    assert differences == ["seed (0, 1 there; 0, 2 here)", "resolution (32 there; 64 here)"]
    described = 'description = "mine"\n' + SMALL
    assert spec_differences(parse_spec(SMALL), parse_spec(described)) == ["description"]


def test_the_same_values_combined_otherwise_differ_too() -> None:
    both = (
        '[[grid]]\nnetwork = ["paper"]\nseed = [0]\n[[grid]]\nnetwork = ["random:8"]\nseed = [1]\n'
    )
    crossed = '[grid]\nnetwork = ["paper", "random:8"]\nseed = [0, 1]\n'
    (difference,) = spec_differences(parse_spec(both), parse_spec(crossed))
    assert "combined into other runs" in difference


def _batch_folder(tmp_path: Path, spec_text: str) -> Path:
    out = tmp_path / "out"
    (out / "runs").mkdir(parents=True)
    (out / "spec.toml").write_text(spec_text)
    (out / "results.csv").write_text(TABLE)
    return out


def test_batch_resume_with_another_spec_is_refused(tmp_path: Path) -> None:
    out = _batch_folder(tmp_path, SMALL)
    other = tmp_path / "other.toml"
    other.write_text(SMALL.replace('"paper", "random:8"', '"paper"'))
    code, lines = cli("batch", str(other), "--out", str(out), "--resume")
    assert code == 2 and len(lines) == 1, lines
    assert (
        "another SPEC" in lines[0]
        and "network ('paper', 'random:8' there; 'paper' here)" in (lines[0])
    )
    assert (out / "results.csv").read_text() == TABLE
    assert (out / "spec.toml").read_text() == SMALL
    assert sorted(p.name for p in out.iterdir()) == ["results.csv", "runs", "spec.toml"]


def test_batch_resume_with_the_folders_own_spec_passes_the_check(tmp_path: Path) -> None:
    """The same SPEC (a copy, recommented) gets past the folder's check: the refusal
    above is the SPEC's difference, not the resume itself (this batch then fails on
    --address, a later check, so that no run starts)."""
    out = _batch_folder(tmp_path, SMALL)
    same = tmp_path / "same.toml"
    same.write_text("# my copy\n" + SMALL)
    code, lines = cli("batch", str(same), "--out", str(out), "--resume", "--address", "bad")
    assert code == 2 and len(lines) == 1 and "--address bad" in lines[0], lines
    assert (out / "results.csv").read_text() == TABLE


@pytest.mark.parametrize(
    ("spec_toml", "message"),
    [(None, "has no spec.toml: it is not a batch folder"), ("[grid\n", "not a valid SPEC")],
    ids=["no-spec", "corrupt-spec"],
)
def test_a_folder_without_a_valid_spec_is_not_resumed(
    tmp_path: Path, spec_toml: str | None, message: str
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.csv").write_text(TABLE)
    if spec_toml is not None:
        (out / "spec.toml").write_text(spec_toml)
    spec = tmp_path / "small.toml"
    spec.write_text(SMALL)
    code, lines = cli("batch", str(spec), "--out", str(out), "--resume")
    assert code == 2 and len(lines) == 1 and message in lines[0], lines
    assert (out / "results.csv").read_text() == TABLE


def test_experiment_resume_at_other_settings_is_refused(tmp_path: Path) -> None:
    text = paper_spec_text(ExperimentSettings(resolution_px=32))
    out = _batch_folder(tmp_path, text)
    (out / "experiment.md").write_text("# the experiment at 32 px\n")
    code, lines = cli("experiment", "paper", "--out", str(out), "--resume", "--seed", "3")
    assert code == 2 and len(lines) == 1, lines
    assert "seed (0 there; 3 here)" in lines[0] and "resolution (32 there; 400 here)" in lines[0]
    assert (out / "results.csv").read_text() == TABLE
    assert (out / "spec.toml").read_text() == text
    assert (out / "experiment.md").read_text() == "# the experiment at 32 px\n"
