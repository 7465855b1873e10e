"""``pipemap view RUN.mcap --web``: rerun's web viewer on 127.0.0.1, seen in a browser.

The test serves a stored run, opens the page in headless Chromium (Debian's
``chromium``, driven over the DevTools protocol: ``tests/chromium.py``), waits until
the recording is drawn and checks the screenshot: the camera view holds a camera
image (the pipe's colours) and the map view holds the map's nodes. The layout is
the view's blueprint (``replay/view_blueprint.py``) in a 1280 x 800 page. Without
Chromium the test fails under CI (the variable ``CI`` set) and is skipped elsewhere.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest

from pipemap.cli import main
from tests.chromium import CHROMIUM, Chromium

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"
LOG = RECORDINGS / "paper_autonomous.mcap"

#: The page's size, and where the blueprint puts the camera and the map in it
#: (x0, y0, x1, y1: inside each view, below its title bar).
PAGE = (1280, 800)
CAMERA = (20, 440, 360, 640)
MAP = (395, 440, 755, 640)
#: How long the viewer may take to load its WebAssembly and the recording.
LOAD_TIMEOUT_S = 240.0


def need_chromium() -> None:
    if CHROMIUM.exists():
        return
    if os.environ.get("CI"):
        pytest.fail(f"{CHROMIUM} is missing: .ci/run installs it (apt-get install -y chromium)")
    pytest.skip(f"{CHROMIUM} is missing (apt-get install -y chromium)")


def region(image: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    x0, y0, x1, y1 = box
    return image[y0:y1, x0:x1]


def shows_camera_image(image: np.ndarray) -> bool:
    """A fifth of the camera view or more is in colour: the viewer's own widgets are
    grey, the pipe's walls brown and orange."""
    hsv = cv2.cvtColor(region(image, CAMERA), cv2.COLOR_BGR2HSV)
    return bool(np.mean(hsv[:, :, 1] > 60) > 0.2)


def shows_map(image: np.ndarray) -> bool:
    """The map view holds drawn nodes: 1% of it or more stands out from its
    background (its most common grey), as node boxes and labels do."""
    grey = cv2.cvtColor(region(image, MAP), cv2.COLOR_BGR2GRAY).astype(int)
    background = np.bincount(grey.ravel()).argmax()
    return bool(np.mean(np.abs(grey - background) > 80) > 0.01)


def listening_addresses(port: int) -> set[str]:
    """The local addresses that listen on TCP ``port`` (``/proc/net/tcp``, IPv4 and 6)."""
    found = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with open(table) as rows:
            for row in list(rows)[1:]:
                local, state = row.split()[1], row.split()[3]
                address, hex_port = local.split(":")
                if state == "0A" and int(hex_port, 16) == port:  # 0A: LISTEN
                    found.add(address)
    return found


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[subprocess.Popen[str], str, Path]]:
    """``pipemap view --web --port P --save`` running, and the page's address."""
    need_chromium()
    saved = tmp_path / "run.rrd"
    with socket.socket() as s:  # a port nothing listens on, as the system found it
        s.bind(("127.0.0.1", 0))
        port = int(s.getsockname()[1])
    command = [sys.executable, "-m", "pipemap", "view", str(LOG), "--web", "--port", str(port)]
    server = subprocess.Popen(
        [*command, "--save", str(saved)],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    try:
        assert server.stdout is not None
        first = server.stdout.readline()
        # 13 visits' sweeps and 5 probe sweeps of the robot's active vision.
        assert first.startswith(f"viewed {LOG}: 18 sweeps, 108 images, 13 visits, 7 junctions")
        line = server.stdout.readline()
        assert line.startswith(f"serving the view at http://127.0.0.1:{port}/?url="), line
        yield server, line.split()[4], saved
    finally:  # the server and its rerun child stop even when a check above failed
        if server.poll() is None:
            server.send_signal(signal.SIGINT)
            server.wait(timeout=30)


def test_the_browser_draws_the_images_and_the_map(
    served: tuple[subprocess.Popen[str], str, Path], tmp_path: Path
) -> None:
    server, url, saved = served
    assert saved.stat().st_size > 0  # --save keeps the recording it serves
    web_port = int(url.split(":")[2].split("/")[0])
    assert listening_addresses(web_port) == {"0100007F"}  # 127.0.0.1 alone
    assert "%3A" in url and "proxy" in url
    grpc_port = int(url.rsplit("%3A", 1)[1].split("%2F")[0])
    assert listening_addresses(grpc_port) == {"0100007F"}

    with Chromium(tmp_path / "profile", *PAGE) as browser:
        browser.open(url)
        deadline = time.monotonic() + LOAD_TIMEOUT_S
        while True:
            time.sleep(3)
            shot = cv2.imdecode(np.frombuffer(browser.screenshot(), np.uint8), cv2.IMREAD_COLOR)
            if shows_camera_image(shot) and shows_map(shot):
                break
            assert time.monotonic() < deadline, "the viewer did not draw the run in time"
    (tmp_path / "web.png").write_bytes(cv2.imencode(".png", shot)[1].tobytes())
    assert shot.shape[:2] == (PAGE[1], PAGE[0])

    # The checks see what they name: the same screenshot without the camera's image,
    # or without the map's nodes, fails them.
    for box, check in ((CAMERA, shows_camera_image), (MAP, shows_map)):
        blanked = shot.copy()
        x0, y0, x1, y1 = box
        # Filled with the grey of the region's median lightness: a median colour is
        # itself in colour when the pipe's walls fill most of the camera's view.
        blanked[y0:y1, x0:x1] = np.median(shot[y0:y1, x0:x1].reshape(-1, 3), axis=0).mean()
        assert check(shot) and not check(blanked)

    server.send_signal(signal.SIGINT)  # Ctrl-C ends the server and rerun with it
    assert server.wait(timeout=30) == 130
    assert not listening_addresses(web_port) and not listening_addresses(grpc_port)


@pytest.mark.parametrize("ci", ["", "true"])
def test_without_chromium_the_test_fails_under_ci_and_is_skipped_elsewhere(
    ci: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(sys.modules[__name__], "CHROMIUM", tmp_path / "no-chromium")
    monkeypatch.setenv("CI", ci)
    expected = pytest.fail.Exception if ci else pytest.skip.Exception
    with pytest.raises(expected, match="no-chromium is missing"):
        need_chromium()


def busy_port() -> tuple[socket.socket, int]:
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    s.listen()
    return s, int(s.getsockname()[1])


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        (["--web", "--port", "70000"], "--port 70000: not a port number from 0 to 65535"),
        (["--web", "--port", "{busy}"], "is in use; choose another port"),
        (["--port", "9090"], "--port: the web viewer's port, so it needs --web"),
    ],
)
def test_bad_web_flags_are_one_line_and_exit_2_before_any_work(
    extra: list[str], expected: str, tmp_path: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    listener, port = busy_port()
    with listener:
        out = tmp_path / "run.rrd"
        argv = ["view", str(LOG), "--save", str(out), *(a.format(busy=port) for a in extra)]
        status = main(argv)
    stdout, stderr = capfd.readouterr()
    assert status == 2 and stdout == ""
    assert len(stderr.splitlines()) == 1 and stderr.startswith("pipemap: error: ")
    assert expected in stderr
    assert not out.exists()  # refused before the replay
