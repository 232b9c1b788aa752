"""python-can's slcan interface, reading the adapter's serial port in blocks.

python-can 4.6's ``slcanBus._read`` takes one byte per ``read(1)`` call, asking
``in_waiting`` before each round, and its port has a 1 ms timeout: with nothing to read
it wakes a thousand times a second. :class:`BlockSlcanBus` is the same bus (commands,
frame parsing, filters, ``send`` are python-can's) whose ``_read`` waits on the port's
file descriptor with ``select`` for the whole timeout, reads whatever is there at once,
and splits the lines on CR (ok and frames) or BEL (error), keeping a partial line for the
next call. Ports without a file descriptor (pyserial URLs such as ``socket://``) keep
python-can's own reader.
"""

from __future__ import annotations

import os
import select
import time
from typing import Any

from can import CanOperationError
from can.interfaces.slcan import slcanBus

_TERMINATORS = (ord("\r"), ord("\a"))


class BlockSlcanBus(slcanBus):
    """An slcan bus that reads in blocks (see the module docstring)."""

    def __init__(self, channel: Any, **kwargs: Any) -> None:
        self._fd: int | None = None
        super().__init__(channel, **kwargs)
        port = self.serialPortOrig
        if type(port).__module__ == "serial.serialposix":
            self._fd = port.fileno()

    @property
    def fd(self) -> int | None:
        """The adapter's port descriptor (None: a port read through python-can's reader)."""
        return self._fd

    def has_line(self) -> bool:
        """A complete line (ok, frame or error) is buffered: ``recv`` returns without
        reading the port."""
        buf = self._buffer
        return b"\r" in buf or b"\a" in buf

    def _line(self) -> str | None:
        """The first complete line of the buffer (with its terminator), taken out of it."""
        buf = self._buffer
        cr, bel = buf.find(b"\r"), buf.find(b"\a")
        end = bel if bel != -1 and (cr == -1 or bel < cr) else cr
        if end == -1:
            return None
        line = buf[: end + 1].decode()
        del buf[: end + 1]
        return line

    def _read(self, timeout: float | None) -> str | None:
        fd = self._fd
        if fd is None:
            return super()._read(timeout)
        try:
            line = self._line()
            if line is not None:
                return line
            deadline = None if timeout is None else time.monotonic() + timeout
            while True:
                left = None if deadline is None else max(0.0, deadline - time.monotonic())
                ready, _, _ = select.select([fd], [], [], left)
                if not ready:
                    return None
                data = os.read(fd, 4096)
                if not data:  # readable with nothing: the adapter (or pty) is gone
                    raise CanOperationError("the slcan adapter closed its port")
                self._buffer += data
                if _TERMINATORS[0] in data or _TERMINATORS[1] in data:
                    return self._line()
                if deadline is not None and time.monotonic() >= deadline:
                    return None
        except CanOperationError:
            raise
        except (OSError, ValueError, UnicodeDecodeError) as exc:
            raise CanOperationError(f"Could not read from serial device: {exc}") from exc
