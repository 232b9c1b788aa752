"""What the localizers share at their message boundary: type dispatch, skip counters, and
the check that a GPS fix carries a usable local position (ekf-vs-cp eq. 4's z).

:class:`MessageIntake` is a mixin: ``feed(msg)`` calls the ``feed_<kind>`` method named in
``FEEDS`` for the message's class; anything else is counted in ``skipped`` as
``unhandled_<Class>`` and ignored, never raised.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from msgs import GpsFix


class MessageIntake:
    FEEDS: ClassVar[dict[type, str]] = {}
    skipped: dict[str, int]

    def _skip(self, why: str) -> None:
        self.skipped[why] = self.skipped.get(why, 0) + 1

    def feed(self, msg: Any) -> Any:
        """Dispatch a message by type (others are ignored and counted)."""
        name = self.FEEDS.get(type(msg))
        if name is None:
            self._skip("unhandled_" + type(msg).__name__)
            return None
        return getattr(self, name)(msg)

    def _gps_position(self, fix: GpsFix, min_mode: int) -> tuple[float, float] | None:
        """(east, north) of a fix good enough to use, else None (counted)."""
        if fix.east_m is None or fix.north_m is None or fix.mode < min_mode:
            self._skip("gps_no_fix")
            return None
        if not (math.isfinite(fix.east_m) and math.isfinite(fix.north_m)):
            self._skip("gps_invalid")
            return None
        return fix.east_m, fix.north_m
