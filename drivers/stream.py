"""A driver for devices that stream on their own (IR board, gyro, GPS) over one byte link.

Owns a transport opened by URL (serial path, ``tcp://``, or a file of recorded bytes) and a
codec; ``read`` returns the decoded messages and reconnects with exponential backoff when
the link breaks or the device stays silent for ``silence_timeout_s``
(drivers.reconnect: back at once when the port's path reappears). Subclasses send
their setup commands in ``_on_open``. A file is decoded as fast as possible, without setup
commands; at its end ``eof`` is true and the codec's pending messages are flushed.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from drivers.base import Clock, DeviceError, LinkDiagnostics, RawHook, wall_clock_ns
from drivers.reconnect import Reconnect, ReconnectingLink, local_path
from drivers.transport import FileTransport, LinkLost, Transport, open_transport


class StreamDriver(LinkDiagnostics, ReconnectingLink):
    """Base of the streaming sensor drivers (see the module docstring)."""

    device = "stream"

    def __init__(
        self,
        url: str,
        codec: Any,
        baud: int = 115200,
        clock: Clock = wall_clock_ns,
        on_raw: RawHook | None = None,
        silence_timeout_s: float = 3.0,
        reconnect_initial_s: float = 0.25,
        reconnect_max_s: float = 1.0,
    ) -> None:
        self.url = url
        self.codec = codec
        self.baud = baud
        self.clock = clock
        self.on_raw = on_raw
        self.silence_timeout_s = silence_timeout_s
        self._rc = Reconnect(reconnect_initial_s, reconnect_max_s, local_path(url))
        self.connected = False
        self.reconnects = 0
        self.last_error = ""
        self._t: Transport | None = None
        self._lock = threading.Lock()
        self._last_rx = 0.0
        self._last_seen_ns = 0
        self._flushed = False

    # -- connection ------------------------------------------------------------------
    def open(self) -> None:
        t = open_transport(self.url, self.baud)
        self._t = t
        try:
            if not isinstance(t, FileTransport):
                self._on_open()
        except (LinkLost, OSError) as exc:
            t.close()
            self._t = None
            raise DeviceError(f"{self.url}: setup failed: {exc}") from None
        self.connected = True
        self._last_rx = time.monotonic()
        self._rc.succeeded()
        self.last_error = ""

    def _on_open(self) -> None:
        """Send setup commands (subclasses)."""

    def write(self, data: bytes) -> bool:
        """Send bytes to the device; False when the link is down (dropped)."""
        with self._lock:
            if self._t is None:
                return False
            try:
                self._t.write(data)
                return True
            except LinkLost as exc:
                self.last_error = str(exc)
                return False

    def fileno(self) -> int | None:
        """The port's descriptor while the link is up and has one (a device path), for a
        selector that calls ``read(0)`` when it is readable; else None."""
        t = self._t
        return t.fileno() if self.connected and t is not None else None

    @property
    def is_file(self) -> bool:
        return isinstance(self._t, FileTransport)

    @property
    def eof(self) -> bool:
        return self.is_file and self._t is not None and self._t.eof

    # -- reading ------------------------------------------------------------------------
    def read(self, timeout_s: float) -> list[Any]:
        if not self.connected:
            self._try_reconnect()
            if not self.connected:
                time.sleep(self._rc.wait_s(time.monotonic(), timeout_s))
                return []
        assert self._t is not None
        try:
            data = self._t.read(4096, timeout_s)
        except LinkLost as exc:
            self._drop_link(str(exc))
            return []
        now = time.monotonic()
        if not data:
            if self.eof:
                if not self._flushed and hasattr(self.codec, "flush"):
                    self._flushed = True
                    return self._seen(self.codec.flush())
                return []
            if not self.is_file and now - self._last_rx > self.silence_timeout_s:
                self._drop_link(f"{self.url}: device silent for {self.silence_timeout_s} s")
            return []
        self._last_rx = now
        stamp = self.clock()
        if self.on_raw:
            self.on_raw(data, stamp)
        return self._seen(self.codec.feed(data, stamp))

    def _seen(self, msgs: list[Any]) -> list[Any]:
        if msgs:
            self._last_seen_ns = getattr(msgs[-1], "stamp_ns", 0)
        return msgs

    def close(self) -> None:
        self.connected = False
        with self._lock:
            if self._t is not None:
                self._t.close()
                self._t = None
