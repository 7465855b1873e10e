"""Entry point of the world's child process (see :mod:`sim.world_process`).

``python -P -m pipemap.sim.world_child REQUESTS_FD REPLIES_FD``: reads the world's
settings, builds it, then answers pickled requests (an image, range rays) until
its requests pipe closes. Not for use by hand.
"""

from __future__ import annotations

import contextlib
import sys
from multiprocessing.connection import Connection
from typing import Any

from pipemap.errors import PipemapError

_METHODS = ("render", "render_tilted", "ray_distances_m")


def serve(requests: Connection, replies: Connection) -> int:
    """Build the world the first message asks for and answer until the pipe closes."""
    from pipemap.sim.world import World

    try:
        config, progress = requests.recv()
    except EOFError:
        return 0
    network, seed, texture_px, cull, obstacles, looks, stream = config

    def on_build(built: int, pieces: int) -> None:
        replies.send(("progress", built, pieces))

    try:
        world = World(
            network,
            seed=seed,
            texture_px=texture_px,
            cull=cull,
            obstacles=obstacles,
            looks=looks,
            on_build=on_build if progress else None,
            stream=stream,
        )
    except PipemapError as exc:
        replies.send(("error", type(exc).__name__, str(exc)))
        return 1
    with world:
        replies.send(_answer(world, None))
        while True:
            try:
                method, args = requests.recv()
            except EOFError:  # the recording process closed it, or died
                return 0
            if method not in _METHODS:
                raise ValueError(f"the world's process has no request {method!r}")
            try:
                result = getattr(world, method)(*args)
            except PipemapError as exc:
                replies.send(("error", type(exc).__name__, str(exc)))
                return 1
            replies.send(_answer(world, result))


def _answer(world: Any, result: object) -> tuple[object, ...]:
    built, pieces = world.pieces_built
    return ("ok", result, built, pieces, world.triangle_count, world.drawn_bodies)


if __name__ == "__main__":
    requests_fd, replies_fd = (int(fd) for fd in sys.argv[1:3])
    requests = Connection(requests_fd, writable=False)
    replies = Connection(replies_fd, readable=False)
    try:
        code = serve(requests, replies)
    except (BrokenPipeError, ConnectionResetError):
        code = 0  # the recording process is gone: nobody to answer
    finally:
        for stream in (requests, replies):
            with contextlib.suppress(OSError):
                stream.close()
    sys.exit(code)
