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

__all__ = ["last_stop", "stopping_on"]

#: The signal that last stopped a block of :func:`stopping_on` (0: none yet). Code
#: that catches the stop where another library may have turned it into a plain
#: ``KeyboardInterrupt`` (Ray's waits do) still learns which signal it was.
_last_stop = [0]


def last_stop() -> int:
    """The number of the signal that last stopped a :func:`stopping_on` block, or 0."""
    return _last_stop[0]


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
        _last_stop[0] = signum
        raise Interrupted(signum)

    for s in signals:
        if previous[s] is not signal.SIG_IGN:
            signal.signal(s, stop)
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler if handler is not None else signal.SIG_DFL)
