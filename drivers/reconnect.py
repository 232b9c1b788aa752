"""When a driver tries to open a lost link again: one policy for every driver.

Exponential backoff from ``initial_s`` to ``max_s`` between failed attempts, but a port
that is a local path (a serial device, a pty, the slcan adapter's port) is watched
cheaply: while its path is absent nothing is tried, and the moment it exists again the
next attempt is made at once, so a replugged cable is back within one read timeout. A
success resets the backoff. Pure apart from the path check (the caller passes the
monotonic time).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

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
