"""The world in a child process, restarted when its memory passes a budget.

PyBullet keeps the memory of every body it built, removed or not, and of every
client it closed (``benchmarks/bench_pybullet_bodies.py``,
``benchmarks/bench_world_memory.py``), so a world in the recording process grows
with every piece the robot has reached. :class:`WorldProcess` keeps the world
(:class:`sim.world.World`, streamed) in a child process of its own and watches that
process's resident memory after every request: past ``memory_budget_mib`` the
child is ended, its memory goes back to the system, and a fresh child builds again,
as the images and range rays first need them, only the pieces near the robot.

Every piece draws its texture from its own seed and a streamed world draws the
images of the whole world to the bit (``tests/sim/test_world_stream.py``), so a
restart changes no image and no range: a log is byte-identical with the world in
this process or in a child restarted any number of times
(``tests/sim/test_world_process.py``).

The robot is kinematic: the world only answers camera images and range rays, so
the child serves exactly those (and the counts the benchmarks read). Requests and
answers are pickled over two pipes of our own. The child runs
``python -P -m pipemap.sim.world_child`` (the working folder off its module path,
as the log writer's process is started) in a session of its own, so that Ctrl-C
reaches the recording process alone; a child that dies (killed, out of memory) is
a :class:`WriteError`, one line and exit 3, never a hang: its pipe closes.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import subprocess
import sys
from collections.abc import Callable
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any

import numpy as np

from pipemap import errors
from pipemap.errors import WriteError
from pipemap.sim.lookalike import LookAlike
from pipemap.sim.network import Network
from pipemap.sim.obstacles import Obstacle

__all__ = ["WORLD_MEMORY_MIB", "WorldProcess", "resident_mib"]

#: Default budget of the world's child process, MiB: past it the child is restarted.
WORLD_MEMORY_MIB = 2048
#: A child that passes its budget within this many requests of starting holds less
#: than one place of the network: the run goes on, rebuilding the same pieces, and
#: says so once.
FEW_REQUESTS = 16
#: What one place needs (docs/performance.md): a fresh child, and a piece in it, MiB.
CHILD_MIB, PIECE_MIB = 125, 15

_PAGE_MIB = os.sysconf("SC_PAGE_SIZE") / (1024 * 1024)
_log = logging.getLogger(__name__)


def resident_mib(pid: int) -> float:
    """Resident memory of process ``pid`` (Linux ``/proc``), MiB; 0.0 if it cannot be told."""
    try:
        fields = Path(f"/proc/{pid}/statm").read_text().split()
    except OSError:
        return 0.0
    return int(fields[1]) * _PAGE_MIB


class WorldProcess:
    """A :class:`sim.world.World` in a child process. Use as a context manager.

    Takes the arguments of ``World`` (but ``stream``: a restarted world is always
    streamed, so the child streams unless asked otherwise at its first start) and
    ``memory_budget_mib``: the child is restarted before the next request once its
    resident memory has passed it.
    """

    def __init__(
        self,
        network: Network,
        seed: int,
        texture_px: int = 512,
        cull: bool = True,
        obstacles: tuple[Obstacle, ...] = (),
        looks: LookAlike | None = None,
        on_build: Callable[[int, int], None] | None = None,
        stream: bool = True,
        memory_budget_mib: float = WORLD_MEMORY_MIB,
    ) -> None:
        if not memory_budget_mib > 0:
            raise errors.SimError(f"world memory budget must be > 0 MiB, got {memory_budget_mib}")
        self.network = network
        self.looks = looks if looks is not None else LookAlike(0.0)
        self.obstacles = tuple(obstacles)
        self.radius_m = network.diameter_m / 2.0
        self.cull = cull
        self.stream = stream
        self.memory_budget_mib = float(memory_budget_mib)
        #: Children started after the first (each a restart past the budget).
        self.restarts = 0
        #: The highest resident memory any child reached, MiB (seen after a request).
        self.peak_child_mib = 0.0
        self.drawn_bodies = 0
        self.triangle_count = 0
        self._built = (0, len(network.pipes) + len(network.nodes))
        self._config = (network, seed, texture_px, cull, self.obstacles, self.looks, stream)
        self._process: subprocess.Popen[bytes] | None = None
        self._requests: Connection | None = None
        self._replies: Connection | None = None
        self._due = False
        #: Requests the current child has answered; whether the budget was called small.
        self._served = 0
        self.budget_warned = False
        self._start(on_build)

    # -- the child --------------------------------------------------------------------

    def _start(self, on_build: Callable[[int, int], None] | None = None) -> None:
        requests_read, requests_write = os.pipe()
        replies_read, replies_write = os.pipe()
        try:
            self._process = subprocess.Popen(
                [
                    sys.executable,
                    "-P",  # the working folder off the path: the installed pipemap
                    "-m",
                    "pipemap.sim.world_child",
                    str(requests_read),
                    str(replies_write),
                ],
                pass_fds=(requests_read, replies_write),
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,  # the command's own output stays its own
                start_new_session=True,
            )
        finally:
            os.close(requests_read)
            os.close(replies_write)
        self._requests = Connection(requests_write, readable=False)
        self._replies = Connection(replies_read, writable=False)
        self._send((self._config, on_build is not None))
        while True:
            reply = self._receive()
            if reply[0] == "progress":
                if on_build is not None:
                    on_build(int(reply[1]), int(reply[2]))
                continue
            self._take(reply)
            return

    def _send(self, message: object) -> None:
        assert self._requests is not None
        try:
            self._requests.send(message)
        except OSError:  # a broken pipe: the child is gone
            raise self._gone() from None

    def _receive(self) -> tuple[Any, ...]:
        assert self._replies is not None
        try:
            reply: tuple[Any, ...] = self._replies.recv()
        except (EOFError, OSError):
            raise self._gone() from None
        if reply[0] == "error":  # a PipemapError in the child: the same here
            kind = getattr(errors, str(reply[1]), errors.SimError)
            self._stop()
            raise kind(str(reply[2]))
        return reply

    def _take(self, reply: tuple[Any, ...]) -> Any:
        """Keep the counts an answer carries; check the child's memory; the result."""
        _, result, built, pieces, triangles, drawn = reply
        self._built, self.triangle_count, self.drawn_bodies = (built, pieces), triangles, drawn
        assert self._process is not None
        rss = resident_mib(self._process.pid)
        self.peak_child_mib = max(self.peak_child_mib, rss)
        if rss > self.memory_budget_mib:
            self._due = True  # restarted before the next request, not in the middle of one
            if self._served < FEW_REQUESTS and not self.budget_warned:
                self.budget_warned = True
                _log.warning(
                    "world: --world-memory %.0f MiB holds less than one place: a fresh "
                    "world process passed it after %d request(s) (%.0f MiB, %d pieces "
                    "built), so it rebuilds the same pieces every few requests; a "
                    "process takes about %d MiB and %d MiB a piece (docs/performance.md)",
                    self.memory_budget_mib,
                    self._served,
                    rss,
                    built,
                    CHILD_MIB,
                    PIECE_MIB,
                )
        return result

    def _gone(self) -> WriteError:
        """The error of a child that ended unasked."""
        process = self._process
        code = process.wait() if process is not None else 0
        self._stop()
        if code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = f"signal {-code}"
            why = f"the world's process was killed ({name})"
        else:
            why = f"the world's process died (exit status {code})"
        return WriteError(f"{why}; the run stops here and its log holds what was recorded before")

    def _stop(self) -> None:
        """End the child (asked to end, then killed if it does not) and close the pipes."""
        for stream in (self._requests, self._replies):
            if stream is not None:
                with contextlib.suppress(OSError):
                    stream.close()
        self._requests = self._replies = None
        process, self._process = self._process, None
        if process is not None and process.poll() is None:
            # The child ends when its requests pipe closes (it removes its texture
            # folder); one that does not within seconds is killed.
            try:
                process.wait(timeout=10.0)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()

    def _call(self, method: str, *args: object) -> Any:
        if self._process is None:
            raise errors.SimError("the world is closed")
        if self._due:
            self._due = False
            assert self._process is not None
            _log.info(
                "world: a fresh process after %.0f MiB (budget %.0f MiB)",
                resident_mib(self._process.pid),
                self.memory_budget_mib,
            )
            self._stop()
            self._start()
            self.restarts += 1
            self._served = 0
        self._send((method, args))
        self._served += 1
        return self._take(self._receive())

    # -- what the robot and the cameras ask ------------------------------------------

    @property
    def pieces_built(self) -> tuple[int, int]:
        """(pieces built in the current child, pieces in all)."""
        return self._built

    def render(
        self,
        eye_xyz_m: tuple[float, float, float],
        yaw_rad: float,
        camera: Any,
        pitch_rad: float = 0.0,
    ) -> np.ndarray:
        """What the camera sees (:meth:`sim.world.World.render`)."""
        image: np.ndarray = self._call("render", eye_xyz_m, yaw_rad, camera, pitch_rad)
        return image

    def render_tilted(
        self,
        eye_xyz_m: tuple[float, float, float],
        heading_rad: float,
        camera_angle_rad: float,
        roll_rad: float,
        pitch_rad: float,
        camera: Any,
    ) -> np.ndarray:
        """What a tilted robot's camera sees (:meth:`sim.world.World.render_tilted`)."""
        image: np.ndarray = self._call(
            "render_tilted", eye_xyz_m, heading_rad, camera_angle_rad, roll_rad, pitch_rad, camera
        )
        return image

    def ray_distances_m(
        self, origins_m: np.ndarray, directions: np.ndarray, max_range_m: float
    ) -> np.ndarray:
        """Distance along each ray to the first wall (:meth:`sim.world.World.ray_distances_m`)."""
        distances: np.ndarray = self._call("ray_distances_m", origins_m, directions, max_range_m)
        return distances

    def restart(self) -> None:
        """Start a fresh child before the next request (as a budget passed does)."""
        self._due = True

    def __enter__(self) -> WorldProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """End the child; it removes its texture files."""
        self._stop()
