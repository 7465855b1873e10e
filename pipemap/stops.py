"""Stop signals raised as Ctrl-C is, shared by the command line and a batch's driver.

Standard library and the error root only, so that every layer above may use it.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType

from pipemap.errors import Interrupted

__all__ = ["stopping_on"]


@contextlib.contextmanager
def stopping_on(signals: tuple[signal.Signals, ...]) -> Iterator[None]:
    """Within the block, the first of ``signals`` raises :class:`Interrupted` naming it,
    and the later ones are ignored while the stop is cleaned up; the handlers before
    are restored after. A signal already ignored (``nohup``'s SIGHUP) stays ignored.
    Only the main thread may set handlers; elsewhere nothing changes."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {s: signal.getsignal(s) for s in signals}

    def stop(signum: int, frame: FrameType | None) -> None:
        for s in signals:
            signal.signal(s, signal.SIG_IGN)
        raise Interrupted(signum)

    for s in signals:
        if previous[s] is not signal.SIG_IGN:
            signal.signal(s, stop)
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler if handler is not None else signal.SIG_DFL)
