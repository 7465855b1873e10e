"""Ctrl-C, SIGTERM and SIGHUP in a batch's driver: both stop it the same way, and neither
lands between the runs of one recording while they are written.

A recording's runs (one per rule) share its log: the first run's folder holds it,
the others link to it. Were they written one by one with Ctrl-C free to land
between, an interrupted batch could keep one rule's run and not the other's, and
``--resume`` would then record the log again for the other alone (a second copy,
no longer linked). :func:`held_signals` makes such a write one step.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator

from pipemap.stops import stopping_on

__all__ = ["held_signals", "terminate_as_interrupt"]

#: The signals that stop a batch.
_STOPS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def terminate_as_interrupt() -> contextlib.AbstractContextManager[None]:
    """SIGTERM (``kill``, a scheduler ending the job) and SIGHUP (the terminal closed)
    stop the batch as Ctrl-C does, as :class:`pipemap.errors.Interrupted` naming the
    signal, and later ones are ignored until the table is written. Without this, the
    handler ``ray.init`` installs exits at once and leaves the table behind the
    finished runs. Only the main thread may set a handler; elsewhere they are left
    alone."""
    return stopping_on((signal.SIGTERM, signal.SIGHUP))


@contextlib.contextmanager
def held_signals() -> Iterator[None]:
    """SIGINT and SIGTERM that arrive in the block take effect when it ends, through
    the handlers that were in place (the first one only: a second stop asks nothing
    more). Only the main thread may set a handler; elsewhere nothing is held."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    arrived: list[int] = []

    def hold(signum: int, frame: object) -> None:
        arrived.append(signum)

    previous = {s: signal.signal(s, hold) for s in _STOPS}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        if arrived:
            signal.raise_signal(arrived[0])
