"""The stamps of a robot's messages: wall time that never goes back.

Every device read, log record and command is stamped in UTC nanoseconds so that logs,
peers and the truth line up. The system's wall clock can step, though. A computer
without a real-time clock (a Raspberry Pi on a Pioneer) boots with a stale time, and
NTP, chrony or a GPS-disciplined daemon then sets it forward, or back when it was ahead.
A step back makes every later message look older than the last one. The filters then
take the steps as out of order: the heading freezes, or (a step of seconds) it takes
the wrong increments and ends far off while still sure of itself.

:class:`SteadyWallClock` is the monotonic clock with an offset to the wall clock.
CLOCK_MONOTONIC runs at the same rate as the wall clock (NTP slews both), so the offset
stays fixed until the wall clock steps:

- a step forward of more than ``step_ns`` (1 s): the stamps follow it (a gap, which the
  filters take like any other);
- a step back: the stamps go on from where they were, ahead of the wall clock by the
  step, and they meet it again at the next step forward (counted in ``back_steps``).

So the stamps never go back and never stall. Thread-safe: a step is looked at under a
lock with both clocks read again, and reading the offset is atomic. A step back is
counted once, until the stamps are within a step of the wall clock again.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

STEP_NS = 1_000_000_000


class SteadyWallClock:
    """Wall time in ns that follows forward steps of the wall clock and never goes back."""

    def __init__(
        self,
        wall: Callable[[], int] = time.time_ns,
        mono: Callable[[], int] = time.monotonic_ns,
        step_ns: int = STEP_NS,
    ) -> None:
        self._wall, self._mono, self.step_ns = wall, mono, int(step_ns)
        self._offset = wall() - mono()
        self._lock = threading.Lock()
        self._behind = False  # the wall clock is behind the stamps (after a step back)
        self.forward_steps = 0
        self.back_steps = 0

    def now_ns(self) -> int:
        t = self._mono() + self._offset
        if abs(self._wall() - t) <= self.step_ns:
            self._behind = False  # with the wall clock again (within a step)
            return t
        with self._lock:  # read both again: another thread may have followed the step
            w = self._wall()
            m = self._mono()  # after the wall clock: a stall between them is no step forward
            t = m + self._offset
            if w - t > self.step_ns:
                self._offset = w - m
                self.forward_steps += 1
                self._behind = False
                t = w
            elif t - w > self.step_ns and not self._behind:
                self._behind = True
                self.back_steps += 1
            return t


CLOCK = SteadyWallClock()


def now_ns() -> int:
    """The robot's stamp for now (:data:`CLOCK`)."""
    return CLOCK.now_ns()
