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
