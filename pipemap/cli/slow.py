"""A line on stderr for a step that takes long with nothing else to show: building
the world of a large network (a 100-junction world takes about a minute). A step done
within :data:`SLOW_S` seconds says nothing. As the other progress lines, it is shown
on a terminal only: a command whose stderr goes to a file or a pipe keeps it to its
warnings and its one error line."""

from __future__ import annotations

import threading
import time
from types import TracebackType
from typing import TextIO

__all__ = ["SLOW_S", "SlowNotice"]

#: How long a step may take before it is announced.
SLOW_S = 3.0


class SlowNotice:
    """Says ``pipemap: WHAT ...`` on ``err`` once the step has taken :data:`SLOW_S`
    seconds, and ``pipemap: DONE in N s`` when it ends after that. Start and stop it
    (or use it as a context manager); stopping twice is harmless."""

    def __init__(self, err: TextIO, what: str, done: str) -> None:
        self._err, self._what, self._done = err, what, done
        self._lock = threading.Lock()
        self._timer: threading.Timer | None = None
        self._started = 0.0
        self._said = False

    def start(self) -> None:
        """Start the step's clock (on a terminal: elsewhere the notice stays silent)."""
        self.stop()
        if not self._err.isatty():
            return
        self._started = time.perf_counter()
        self._said = False
        self._timer = threading.Timer(SLOW_S, self._say)
        self._timer.daemon = True
        self._timer.start()

    def _say(self) -> None:
        with self._lock:
            if self._timer is None:
                return
            self._err.write(f"pipemap: {self._what} ...\n")
            self._err.flush()
            self._said = True

    def stop(self) -> None:
        """The step is done: say how long it took if it was announced."""
        with self._lock:
            if self._timer is None:
                return
            self._timer.cancel()
            self._timer = None
            if self._said:
                seconds = time.perf_counter() - self._started
                self._err.write(f"pipemap: {self._done} in {seconds:.0f} s\n")
                self._err.flush()

    def __enter__(self) -> SlowNotice:
        self.start()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()
