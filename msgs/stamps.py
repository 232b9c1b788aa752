"""One rule for every stream of stamped messages: when is an older stamp a clock set back?

Messages come out of order by milliseconds (readers racing, bursts read at once), and
the filters count and skip those. A stamp more than :data:`SET_BACK_NS` (1 s) older than
the last of its stream is something else: the clock that stamped it was set back (a
log recorded while NTP stepped the wall clock; the daemon's own stamps never go back,
drivers.clock). Skipping would skip every later message too, so each filter follows
it instead, as a new start of its stream (a baseline), and counts it.
"""

from __future__ import annotations

SET_BACK_NS = 1_000_000_000


def set_back(stamp_ns: int, last_ns: int) -> bool:
    """Whether ``stamp_ns`` is more than :data:`SET_BACK_NS` older than ``last_ns``."""
    return last_ns - stamp_ns > SET_BACK_NS


class SetBackGate:
    """One stream's check that a set back is real before it is followed.

    A first message more than a second older than the stream's last is held: it may be
    a stray (one message with a wrong stamp in a log) as well as the first after a step.
    The next message confirms the step when it continues from the held one (newer than
    it by at most a second, and still set back from the last); the stream then starts
    again there. A message newer than the last shows the held one was a stray. So one
    message with a wrong stamp is skipped, as before the rule, and a stream whose clock
    was set back loses one message more than it would by following at once."""

    def __init__(self) -> None:
        self.held_ns: int | None = None

    def older(self, stamp_ns: int, last_ns: int) -> str:
        """For a message not newer than the stream's last: "late" (within a second: count
        and skip it), "held" (a first one more than a second back: skip it for now) or
        "confirmed" (it continues from the held one: start the stream again here)."""
        if not set_back(stamp_ns, last_ns):
            return "late"
        h = self.held_ns
        if h is not None and h < stamp_ns <= h + SET_BACK_NS:
            self.held_ns = None
            return "confirmed"
        self.held_ns = stamp_ns
        return "held"

    def newer(self) -> None:
        """A message newer than the stream's last: a held one was a stray."""
        self.held_ns = None
