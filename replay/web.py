"""A saved view served in rerun's web viewer, on the loopback interface only.

``pipemap view RUN.mcap --web`` is for machines without a display: the view is saved
as an ``.rrd`` file (:func:`pipemap.replay.view.save_view`) and rerun's own command
serves it, ``rerun --serve-web --bind 127.0.0.1``: an HTTP server for the web viewer
(HTML, JavaScript and WebAssembly, all inside the rerun-sdk wheel, so no network is
needed) and a gRPC server holding the recording, which the viewer page reads. Both
listen on 127.0.0.1 alone. rerun's Python ``serve_web_viewer`` cannot be used for
this: it listens on every interface (0.0.0.0) and takes no address.

The page's address names the gRPC server in its ``url`` parameter, as rerun's own
web viewer expects (``http://127.0.0.1:P/?url=rerun%2Bhttp%3A%2F%2F127.0.0.1%3AG%2Fproxy``).
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import socket
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import quote

from pipemap.errors import InputError, ViewerError

__all__ = ["LOOPBACK", "WebServer", "check_web_port", "rerun_executable", "serve_web", "stop"]

#: The only address the web viewer and its gRPC server listen on.
LOOPBACK = "127.0.0.1"
#: How long rerun may take to open both ports before the view is given up.
START_TIMEOUT_S = 30.0


def rerun_executable() -> Path:
    """The ``rerun`` program of the installed rerun-sdk (``RERUN_CLI_PATH`` overrides
    it, as rerun's own launcher allows)."""
    override = os.environ.get("RERUN_CLI_PATH")
    if override:
        path = Path(override)
    else:
        spec = importlib.util.find_spec("rerun_cli")
        if spec is None or spec.origin is None:
            raise ViewerError("--web: the rerun command of rerun-sdk is not installed")
        path = Path(spec.origin).parent / "rerun"
    if not os.access(path, os.X_OK):
        raise ViewerError(f"--web: the rerun command {path} is missing or not executable")
    return path


def _free(port: int) -> bool:
    with socket.socket() as s:
        try:
            s.bind((LOOPBACK, port))
        except OSError:
            return False
        return True


def _any_free_port() -> int:
    with socket.socket() as s:
        s.bind((LOOPBACK, 0))
        return int(s.getsockname()[1])


def check_web_port(port: int) -> None:
    """``--port``: a port number, free on the loopback interface (0: any free one).
    Checked before the log is replayed."""
    if not 0 <= port <= 65535:
        raise InputError(f"--port {port}: not a port number from 0 to 65535")
    if port != 0 and not _free(port):
        raise ViewerError(f"--port {port}: {LOOPBACK}:{port} is in use; choose another port")


def _answers(port: int) -> bool:
    try:
        socket.create_connection((LOOPBACK, port), timeout=1.0).close()
    except OSError:
        return False
    return True


@dataclass(frozen=True)
class WebServer:
    """rerun's web viewer serving one recording: its page's address, and the process."""

    url: str
    web_port: int
    grpc_port: int
    process: subprocess.Popen[bytes]


def _last_line(path: Path) -> str:
    with contextlib.suppress(OSError):
        lines = path.read_text(errors="replace").strip().splitlines()
        if lines:
            return lines[-1].strip()
    return "no message"


@contextlib.contextmanager
def serve_web(rrd: Path, web_port: int, messages: Path) -> Iterator[WebServer]:
    """Serve ``rrd`` in rerun's web viewer on ``web_port`` of 127.0.0.1 (0: a free
    port) until the block ends; rerun's own messages go to the file ``messages``.

    Yields once both of rerun's ports answer; a rerun that ends before that, or does
    not open them within :data:`START_TIMEOUT_S`, is a :class:`ViewerError`. The gRPC
    port is one the system found free a moment before rerun starts.
    """
    program = rerun_executable()
    if web_port == 0:
        web_port = _any_free_port()
    grpc_port = _any_free_port()
    command = [
        str(program),
        "--serve-web",
        "--bind",
        LOOPBACK,
        "--port",
        str(grpc_port),
        "--web-viewer-port",
        str(web_port),
        str(rrd),
    ]
    env = {**os.environ, "RERUN_ANALYTICS": "false"}
    with messages.open("wb") as log:
        process = subprocess.Popen(
            command, stdin=subprocess.DEVNULL, stdout=log, stderr=log, env=env
        )
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while not (_answers(web_port) and _answers(grpc_port)):
            if process.poll() is not None:
                raise ViewerError(
                    f"rerun's web viewer ended at its start (status {process.returncode}): "
                    f"{_last_line(messages)}"
                )
            if time.monotonic() > deadline:
                raise ViewerError(
                    f"rerun's web viewer did not open {LOOPBACK}:{web_port} and "
                    f"{LOOPBACK}:{grpc_port} within {START_TIMEOUT_S:.0f} s"
                )
            time.sleep(0.1)
        proxy = f"rerun+http://{LOOPBACK}:{grpc_port}/proxy"
        url = f"http://{LOOPBACK}:{web_port}/?url={quote(proxy, safe='')}"
        yield WebServer(url, web_port, grpc_port, process)
    finally:
        stop(process, timeout_s=5.0)


def stop(process: subprocess.Popen[Any], timeout_s: float) -> None:
    """End ``process`` if it still runs: SIGTERM, then SIGKILL after ``timeout_s``."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
