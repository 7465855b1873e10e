"""Where a decision's time goes, for a caller that times it.

The localizer reads no clock: same input, same output. A caller that wants to know
where a decision's time goes gives :class:`localizer.localizer.Localizer` one
(``time.perf_counter``, say). Each stretch of :meth:`Localizer.localize` is then
charged to one of :data:`PHASES`:

- ``ncc``: the lamp's normalisation, the matcher's preparation, screening and
  refinement, and the same for each probe sweep (with the probe source's own time:
  a replay looks a probe's sweep up, a robot would move and sweep);
- ``keypoints``: ORB on the sweep (only with the two-view check);
- ``check``: the choice among the candidates, by the two-view fits and the port
  check, or by the threshold;
- ``map``: adding a new junction to the index, and the visit to the map.

The phases add up to the whole call, less the clock's own reading.
"""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["PHASES", "PhaseClock"]

#: The phases of a decision, in the order a decision passes through them.
PHASES = ("ncc", "keypoints", "check", "map")


class PhaseClock:
    """Charges the time since its last lap to a phase. With no clock (``now`` is
    ``None``) it does nothing and :attr:`seconds` stays empty."""

    def __init__(self, now: Callable[[], float] | None) -> None:
        self._now = now
        #: Seconds charged to each phase so far.
        self.seconds: dict[str, float] = {} if now is None else dict.fromkeys(PHASES, 0.0)
        self._mark = 0.0 if now is None else now()

    def lap(self, phase: str) -> None:
        """Charge the time since the last lap (or the start) to ``phase``."""
        if self._now is None:
            return
        now = self._now()
        self.seconds[phase] += now - self._mark
        self._mark = now
