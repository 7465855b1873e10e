"""``pipemap sim`` end to end, and what the localizer makes of a simulated tour."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from pipemap.cli import main
from pipemap.imagesets import load_image_set, read_info
from pipemap.localizer import DEFAULT_THRESHOLD, pairwise_matches, wrap_angle_rad


def _run(argv: list[str], capfd: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        status = main(argv)
    except SystemExit as exc:  # argparse errors
        status = int(exc.code or 0)
    out, err = capfd.readouterr()
    return status, out, err


def test_sim_writes_every_sweep_in_the_paper_layout(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "run"
    status, out, err = _run(
        ["sim", "--network", "paper", "--resolution", "64", "--save-sweeps", str(target)], capfd
    )
    assert status == 0, err
    assert "13 visits of 7/7 nodes" in out and "complete" in out
    folders = sorted(target.iterdir())
    assert [f.name for f in folders] == [f"{i:04d}" for i in range(1, 14)]
    nodes = [read_info(f)["node"] for f in folders]
    assert nodes == list("SABACDCFCECAS")
    info = read_info(folders[1])
    # At A, facing north (pi/2): the sweep starts at the nearest multiple of 60 degrees
    # to the robot's gyro estimate of its heading, 120 (a tie with 60, broken as
    # math.remainder does), less the gyro's error since the start (a few mrad):
    # info.txt has the camera's yaw, sweep.txt the camera's angle to the heading,
    # which the localizer reads.
    assert float(info["y"]) == pytest.approx(1.5)
    assert float(info["yaw"]) == pytest.approx(2 * math.pi / 3, abs=0.01)
    first = load_image_set(folders[1])
    assert first.camera_angle_rad == pytest.approx(math.pi / 6, abs=0.01)
    assert load_image_set(folders[0]).images.shape == (6, 64, 64)


def test_no_align_sweeps_starts_straight_ahead_as_in_the_paper(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "paper-style"
    argv = ["sim", "--network", "paper", "--resolution", "32", "--no-align-sweeps"]
    status, _, err = _run([*argv, "--save-sweeps", str(target)], capfd)
    assert status == 0, err
    folders = sorted(target.iterdir())
    assert float(read_info(folders[1])["yaw"]) == pytest.approx(math.pi / 2)
    # sweep.txt says how the sweep was lit, and nothing of a camera angle.
    assert not any("camera_angle" in (f / "sweep.txt").read_text() for f in folders)
    assert all(load_image_set(f).camera_angle_rad == 0.0 for f in folders)


def test_sim_refuses_to_overwrite_and_bad_input_is_one_line(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    full = tmp_path / "full"
    full.mkdir()
    (full / "keep.txt").write_text("precious")
    cases = [
        (["--network", "paper", "--save-sweeps", str(full)], str(full)),
        (["--network", "nowhere", "--save-sweeps", str(tmp_path / "a")], "nowhere"),
        (["--network", "paper", "--start", "Q", "--save-sweeps", str(tmp_path / "b")], "Q"),
        (["--network", "paper", "--resolution", "5", "--save-sweeps", str(tmp_path / "d")], "5"),
    ]
    for args, named in cases:
        status, out, err = _run(["sim", *args], capfd)
        assert status == 2, args
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("pipemap: error:") and named in lines[0], err
        assert "Traceback" not in err
    assert (full / "keep.txt").read_text() == "precious"


def _heading(folder: Path) -> float:
    """The robot's true heading at a sweep: the camera's yaw less its angle to the heading."""
    return float(read_info(folder)["yaw"]) - load_image_set(folder).camera_angle_rad


def test_every_decision_on_the_perfect_paper_tour_is_right(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    # In the noise condition (3 cm off centre) this does not hold on every seed: see
    # the README's simulator section for the measured rates.
    target = tmp_path / "perfect"
    argv = ["sim", "--network", "paper", "--condition", "perfect"]
    status, _, err = _run([*argv, "--save-sweeps", str(target)], capfd)
    assert status == 0, err
    folders = sorted(target.iterdir())
    status, out, err = _run(["map", "--json", *map(str, folders)], capfd)
    assert status == 0, err
    visits = json.loads(out)["visits"]
    truth = [read_info(f)["node"] for f in folders]
    first_visit: dict[str, int] = {}
    for i, (visit, node) in enumerate(zip(visits, truth, strict=True)):
        if node in first_visit:
            # A revisit is recognised as the node it is, and the rotation between the
            # two visits is the true heading change (the candidate's heading less the
            # query's: the query is set A of Algorithm 2).
            assert visit["known"], (i, node, visit["similarity"])
            assert visit["node"] == visits[first_visit[node]]["node"]
            turn = wrap_angle_rad(_heading(folders[first_visit[node]]) - _heading(folders[i]))
            assert abs(wrap_angle_rad(visit["rotation_pinhole_rad"] - turn)) < 0.01
            assert abs(wrap_angle_rad(visit["rotation_rad"] - turn)) < 0.01
        else:
            assert not visit["known"], (i, node, visit["similarity"])
            first_visit[node] = i


def test_perfect_tour_separates_same_from_different_junctions(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "perfect"
    argv = ["sim", "--network", "paper", "--lighting", "even"]  # the paper's simulation
    status, _, err = _run([*argv, "--save-sweeps", str(target)], capfd)
    assert status == 0, err
    folders = sorted(target.iterdir())
    sets = [load_image_set(f) for f in folders]
    nodes = [read_info(f)["node"] for f in folders]
    different = []
    for (i, j), m in pairwise_matches(sets).items():
        if nodes[i] != nodes[j]:
            different.append(m.similarity)
        else:
            # Aligned sweeps from the same spot: whatever pipe the robot came by, it
            # sees along the same directions, so the images agree almost exactly.
            assert m.similarity > 0.9, (nodes[i], m.similarity)
            turn = wrap_angle_rad(_heading(folders[j]) - _heading(folders[i]))
            assert abs(wrap_angle_rad(m.rotation_rad - turn)) < 0.01
    # At the paper's quarter scale our renderer's look-alike junctions pass the
    # paper's threshold (up to 0.415 here, issue 17), which is why pipemap decides by
    # the two-view check; the similarity still ranks them far below revisits (> 0.9).
    assert max(different) < 0.5
    assert float(np.median(different)) < DEFAULT_THRESHOLD


def test_autonomous_run_saves_a_sweep_at_every_visit(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "auto"
    # 64 px: at 32 px the paper's similarity merges dead ends and the map-driven robot
    # stops on its inconsistent map.
    argv = ["sim", "--network", "paper", "--condition", "autonomous", "--resolution", "64"]
    status, out, err = _run([*argv, "--save-sweeps", str(target)], capfd)
    assert status == 0, err
    assert "finished" in out and "7/7 nodes" in out
    nodes = [read_info(f)["node"] for f in sorted(target.iterdir())]
    assert nodes == list("SABACDCFCECAS")
    assert "explore map" in out
    # sweep.txt holds what the robot noted, so `pipemap map` over the folders gives
    # the map its ports, as a replay of the run's log would.
    notes = (target / "0002" / "sweep.txt").read_text()
    assert "exits: " in notes and "departure: " in notes and "odometer_m: " in notes
    status, out, err = _run(["map", *map(str, sorted(target.iterdir())), "--json"], capfd)
    assert status == 0, err
    doc = json.loads(out)
    assert [len(n["ports"]) for n in doc["nodes"]][:3] == [1, 3, 1]
    assert all(e["u_port"] is not None and e["v_port"] is not None for e in doc["edges"])
    assert doc["visits"][1]["arrival_port"] == 0


def test_images_per_sweep_is_configurable(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    # The paper's Figure 6 compares 6, 9, 18 and 36 images per sweep.
    target = tmp_path / "nine"
    argv = ["sim", "--network", "paper", "--resolution", "32", "--images", "9"]
    status, _, err = _run([*argv, "--save-sweeps", str(target)], capfd)
    assert status == 0, err
    assert load_image_set(sorted(target.iterdir())[0]).count == 9
    status, _, err = _run([*argv[:-1], "1", "--save-sweeps", str(tmp_path / "one")], capfd)
    assert status == 2 and "images per sweep" in err


def test_a_run_that_misses_nodes_is_not_reported_finished(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # The robot may believe it is back at the start when it is not; the simulator knows.
    import numpy as np

    from pipemap.recorder import session
    from pipemap.sim.controller import ExplorationResult, RunStatus
    from pipemap.sim.episode import Pose, Sweep, SweepTruth
    from pipemap.sim.stream import NodeArrival, SweepEnd, SweepImage, SweepStart

    policies = []
    faults = []

    def one_sweep_run(  # type: ignore[no-untyped-def]
        world,
        camera,
        seed,
        start=None,
        config=None,
        sink=None,
        policy=None,
        motor_faults=(),
        on_explorer=None,
        robot_spec=None,
    ):
        policies.append(policy)
        faults.append(motor_faults)
        images = np.zeros((6, 32, 32, 3), np.uint8)
        sweep = Sweep(images)
        truth = SweepTruth("S", Pose(0.0, 0.0, 0.05))
        # One visit's records, as the explorer sends them, and it believes it is done.
        sink(NodeArrival(0, 1))
        sink(SweepStart(0, 1, 1, 6, 0.0, camera.fov_rad))
        for j, image in enumerate(images):
            sink(SweepImage(0, 1, 1, j, 0.0, image))
        sink(SweepEnd(0, 1, 1, sweep, truth))
        return ExplorationResult(
            RunStatus.FINISHED, sweeps=[sweep], sweep_truths=[truth], distance_m=1.0
        )

    # sim runs the episode that record runs (pipemap.recorder.session).
    monkeypatch.setattr(session, "autonomous_run", one_sweep_run)
    argv = ["sim", "--network", "paper", "--condition", "autonomous", "--resolution", "32"]
    status, out, _ = _run([*argv, "--save-sweeps", str(tmp_path / "early")], capfd)
    assert status == 1
    assert "1/7 nodes" in out and "stopped early" in out
    assert (tmp_path / "early" / "0001" / "info.txt").is_file()  # what was produced is kept
    # --explore hands the controller its policy: the map's by default, or the paper's.
    status, out, _ = _run(
        [*argv, "--explore", "right-hand", "--save-sweeps", str(tmp_path / "rh")], capfd
    )
    from pipemap.recorder.online import MapPolicy
    from pipemap.sim.policy import RightHandPolicy

    assert [type(p) for p in policies] == [MapPolicy, RightHandPolicy]
    assert "explore right-hand" in out
    # --motor-faults hands it the cut-outs drawn from the seed (none by default).
    _, out, _ = _run([*argv, "--motor-faults", "2", "--save-sweeps", str(tmp_path / "mf")], capfd)
    assert "; 2 motor cut-outs: got past 0 stall(s), gave up 0 pipe(s)" in out
    from pipemap.sim.motor_faults import draw_motor_faults
    from pipemap.sim.network import build_network

    assert faults[0] == () and faults[-1] == draw_motor_faults(build_network("paper"), 2, 0)
    assert len(faults[-1]) == 2


def test_lighting_even_turns_the_lamp_off(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """The lamp is on by default; ``--lighting even`` gives the paper's evenly lit look."""
    images = {}
    for lighting in ("lamp", "even", None):
        target = tmp_path / str(lighting)
        argv = ["sim", "--network", "paper", "--resolution", "32"]
        argv += [] if lighting is None else ["--lighting", lighting]
        status, _, err = _run([*argv, "--save-sweeps", str(target)], capfd)
        assert status == 0, err
        images[lighting] = np.stack([load_image_set(f).images for f in sorted(target.iterdir())])
    assert np.array_equal(images[None], images["lamp"])
    # Under the lamp alone the far pipe is dark: its darkest tenth is much darker.
    assert np.percentile(images["lamp"], 10) < 0.5 * np.percentile(images["even"], 10)


def test_map_normalises_image_folders_as_their_sweeps_say(
    tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "run"
    argv = ["sim", "--network", "paper", "--resolution", "32", "--save-sweeps", str(target)]
    assert _run(argv, capfd)[0] == 0
    folders = [str(f) for f in sorted(target.iterdir())]
    docs = {}
    for illumination in ("auto", "even", "lamp"):
        status, out, err = _run(["map", *folders, "--json", "--illumination", illumination], capfd)
        assert status == 0, err
        docs[illumination] = [v["similarity"] for v in json.loads(out)["visits"]]
    # pipemap sim's sweeps are lamp-lit by default, and their sweep.txt say so.
    assert docs["auto"] == docs["lamp"] != docs["even"]


@pytest.mark.parametrize("condition", ["perfect", "autonomous"])
def test_sim_runs_the_episode_that_record_runs(
    tmp_path: Path, capfd: pytest.CaptureFixture[str], condition: str
) -> None:
    """``sim`` and ``record`` on the same flags make the same run: the same sweeps (to
    the grey level the two grey conversions round differently), started at the same
    camera angles, at the same true nodes, with the same exits noted, and the same
    decisions by the localizer."""
    from pipemap import api
    from pipemap.imagesets import read_robot_notes
    from pipemap.localizer import LocalizerConfig

    # At 32 px the map-driven robot stops early on its inconsistent map (exit 1): the
    # same for both, as the run is the same.
    argv = ["--network", "paper", "--condition", condition, "--resolution", "32"]
    log = tmp_path / "run.mcap"
    folder = tmp_path / "sweeps"
    recorded_status = _run(["record", *argv, "-o", str(log)], capfd)[0]
    assert _run(["sim", *argv, "--save-sweeps", str(folder)], capfd)[0] == recorded_status
    recorded = api.open_log(log)
    folders = sorted(folder.iterdir())
    visits = recorded.visits()
    assert len(folders) == len(visits) >= 2
    for visit, saved in zip(visits, folders, strict=True):
        images = load_image_set(saved)
        assert np.abs(visit.frames.astype(np.float64) - images.images).max() <= 1.0
        assert images.camera_angle_rad == visit.camera_angle_rad
    # Image-set folders hold no dead reckoning, so the log is replayed without the
    # odometry check to decide on what the folders hold.
    replayed = api.replay(recorded, LocalizerConfig(odometry_check=False)).document()["visits"]
    mapped = api.map_image_sets(folders)["visits"]
    assert [v["exits_rad"] for v in mapped] == [v["exits_rad"] for v in replayed]
    assert [(v["node"], v["known"]) for v in mapped] == [(v["node"], v["known"]) for v in replayed]
    assert all(read_robot_notes(f).exits_rad is not None for f in folders)
