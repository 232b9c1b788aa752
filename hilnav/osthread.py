"""Threads whose names reach the operating system.

Python names its threads for itself only: ``top -H``, ``ps -L``, ``py-spy`` aside and
``/proc/PID/task/*/comm`` show every thread of the daemon as ``python3``, next to
Zenoh's own named threads. A :class:`NamedThread` gives its name (its first 15 bytes,
the kernel's limit) to its OS thread as it starts (``prctl(PR_SET_NAME)``), so an
operator on the robot sees which of the daemon's threads (``services``, ``mapping``,
``watchdog``, ``mcap-flush``) uses the CPU, and ``bench/daemon.py`` reports each.
Where the C library or prctl is not there (not Linux), it is a plain thread.
"""

from __future__ import annotations

import ctypes
import threading

_PR_SET_NAME = 15

try:
    _PRCTL = ctypes.CDLL(None).prctl  # the C library's, already in the process
except (OSError, AttributeError):
    _PRCTL = None


def name_this_thread(name: str) -> bool:
    """Give the calling thread's OS thread ``name`` (15 bytes at most); False if not done."""
    if _PRCTL is None:
        return False
    try:
        return _PRCTL(_PR_SET_NAME, name.encode("utf-8", "replace")[:15], 0, 0, 0) == 0
    except (OSError, ctypes.ArgumentError):
        return False


class NamedThread(threading.Thread):
    """A :class:`threading.Thread` whose OS thread carries its name (module docstring)."""

    def run(self) -> None:
        name_this_thread(self.name)
        super().run()
