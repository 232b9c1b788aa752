"""A virtual serial port: a pty in raw mode, found by a stable symlink.

The emulator holds the master side; a driver opens the slave by the symlink path
(like /dev/serial/by-id/... on a real robot), so the port can *vanish* (pty closed,
symlink removed: the driver's reads fail as when a USB cable is pulled) and *reappear*
under the same path. Writes may be paced at a baud rate (10 bits per byte, 8N1).
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
import tty
from pathlib import Path


class VirtualSerialPort:
    """One emulated device port (see the module docstring)."""

    def __init__(self, link: str | Path, baud: int | None = None) -> None:
        self.link = Path(link)
        self.baud = baud
        self._lock = threading.Lock()
        self.master: int | None = None
        self._slave: int | None = None
        self.pts = ""
        self._open()

    def _open(self) -> None:
        master, slave = os.openpty()
        tty.setraw(slave)
        tty.setraw(master)
        os.set_blocking(master, False)
        self.master, self._slave = master, slave
        self.pts = os.ttyname(slave)
        tmp = self.link.with_name(self.link.name + ".tmp")
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        tmp.symlink_to(self.pts)
        tmp.replace(self.link)

    @property
    def path(self) -> str:
        return str(self.link)

    @property
    def present(self) -> bool:
        return self.master is not None

    def read(self, timeout_s: float, max_bytes: int = 4096) -> bytes:
        """Bytes the driver wrote (empty on timeout or while vanished)."""
        fd = self.master
        if fd is None:
            time.sleep(timeout_s)
            return b""
        try:
            ready, _, _ = select.select([fd], [], [], timeout_s)
            if not ready:
                return b""
            return os.read(fd, max_bytes)
        except (OSError, ValueError):
            return b""

    def write(self, data: bytes, *, block: bool = True, stop: threading.Event | None = None) -> int:
        """Send bytes to the driver, paced at ``baud`` if set; dropped while vanished.

        Blocking (default): waits while the pty's buffer is full, until ``stop`` is set.
        ``block=False``: what does not fit in the buffer is lost, as on a real UART.
        Returns how many bytes were lost for a full buffer."""
        with self._lock:
            fd = self.master
            if fd is None:
                return 0
            view = memoryview(data)
            while view and not (stop is not None and stop.is_set()):
                try:
                    n = os.write(fd, view)
                except BlockingIOError:
                    if not block:
                        return len(view)
                    select.select([], [fd], [], 0.05)
                    continue
                except OSError:
                    return 0
                view = view[n:]
            if self.baud:
                time.sleep(len(data) * 10.0 / self.baud)
            return len(view)

    def vanish(self) -> None:
        """Close the pty and remove the link: the driver sees its port disappear."""
        with self._lock:
            for fd in (self.master, self._slave):
                if fd is not None:
                    with contextlib.suppress(OSError):
                        os.close(fd)
            self.master = self._slave = None
            with contextlib.suppress(FileNotFoundError):
                self.link.unlink()

    def reappear(self) -> None:
        """A new pty under the same link path (the cable plugged back in)."""
        with self._lock:
            if self.master is None:
                self._open()

    def close(self) -> None:
        self.vanish()
