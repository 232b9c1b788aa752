"""When a driver tries to open a lost link again: one policy for every driver.

Exponential backoff from ``initial_s`` to ``max_s`` between failed attempts, but a port
that is a local path (a serial device, a pty, the slcan adapter's port) is watched
cheaply: while its path is absent nothing is tried, and the moment it exists again the
next attempt is made at once, so a replugged cable is back within one read timeout. A
success resets the backoff. :class:`Reconnect` is pure apart from
the path check (the caller passes the monotonic time); :class:`ReconnectingLink` is the
bookkeeping every byte-link driver shares (drop the link, try it again).
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from typing import Any

from drivers.base import DeviceError
from drivers.transport import LinkLost

POLL_S = 0.05  # how often a driver without a link looks for its port


def local_path(url: str) -> str | None:
    """The filesystem path of a port, or None for network URLs and bus channel names."""
    if "://" in url or not url.startswith("/"):
        return None
    return url


@dataclass
class Reconnect:
    initial_s: float = 0.25
    max_s: float = 1.0
    path: str | None = None  # the local path to watch, if any
    backoff_s: float = 0.25
    retry_at: float = 0.0
    _absent: bool = False

    def __post_init__(self) -> None:
        self.backoff_s = self.initial_s

    def due(self, now: float) -> bool:
        """Try opening now?"""
        if self.path is not None:
            if not os.path.exists(self.path):
                self._absent = True
                return False
            if self._absent:  # it just came back
                self._absent = False
                return True
        return now >= self.retry_at

    def wait_s(self, now: float, limit_s: float) -> float:
        """How long to sleep before asking :meth:`due` again (at most ``limit_s``)."""
        if self.path is not None:
            return min(limit_s, POLL_S)
        return min(limit_s, max(0.0, self.retry_at - now))

    def lost(self, now: float) -> None:
        """The link broke: the first retry waits the current backoff."""
        self.retry_at = now + self.backoff_s

    def failed(self, now: float) -> None:
        """An attempt failed: wait twice as long next time (up to ``max_s``)."""
        self.backoff_s = min(self.backoff_s * 2.0, self.max_s)
        self.retry_at = now + self.backoff_s

    def succeeded(self) -> None:
        self.backoff_s = self.initial_s
        self._absent = False


class ReconnectingLink:
    """Mixin of a driver on one transport: expects ``open()``, ``_t`` (the transport),
    ``_lock``, ``_rc`` (a :class:`Reconnect`), ``connected``, ``reconnects`` and
    ``last_error``. ``last_drop`` keeps why the link last went (``last_error`` is cleared
    when it comes back)."""

    _t: Any
    _lock: Any
    _rc: Reconnect
    last_drop: str = ""

    def _drop_link(self, why: str) -> None:
        self.last_error = self.last_drop = why
        self.connected = False
        with self._lock:
            if self._t is not None:
                self._t.close()
                self._t = None
        self._rc.lost(time.monotonic())

    def _try_reconnect(self) -> None:
        if not self._rc.due(time.monotonic()):
            return
        try:
            self.open()  # type: ignore[attr-defined]
            self.reconnects += 1
        except (DeviceError, LinkLost, OSError) as exc:
            self.last_error = str(exc)
            self._rc.failed(time.monotonic())
