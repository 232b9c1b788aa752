"""The contract every device codec and driver follows, so the daemon can wire any of them.

A *codec* is pure: ``feed(data, stamp_ns)`` takes whatever bytes arrived (any split,
any garbage) and returns the messages completed by them; it never raises on input and
keeps :class:`CodecStats`. A *driver* owns a transport, does the device's handshake and
keep-alive, and offers ``read(timeout_s)``: block at most ``timeout_s``, return the
decoded messages (possibly none), reconnect by itself when the link drops. The daemon
waits on the drivers' ``fileno()`` (where a driver has one: a port on a device path) with
one selector and calls ``read(0)`` when it is readable; a driver without one is read by a
thread calling ``read(timeout)`` in a loop. ``on_raw`` sees every chunk of raw bytes (for
the MCAP log). Stamps come from an injected ``clock`` (ns), so replay
from a file can use recorded time.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from drivers.clock import now_ns
from msgs import DeviceDiagnostics

Clock = Callable[[], int]
RawHook = Callable[[bytes, int], None]


wall_clock_ns = now_ns
"""Default clock of drivers: UTC wall time in nanoseconds that never goes back
(:mod:`drivers.clock`: it follows the wall clock's steps forward, not back)."""


@dataclass
class CodecStats:
    """Counters a codec keeps about its input stream.

    ``frames_ok`` counts frames that passed the framing checks (sync, length, checksum);
    ``malformed`` counts those among them whose content could not be turned into a message
    (too short for their type, a channel count other than the configured one, a date that
    cannot be). ``frames_lost`` counts gaps in sequence numbers, where the protocol has
    them; ``duplicates`` counts frames repeating the previous one (same sequence number and
    content), which are dropped and not in ``frames_ok``.
    """

    frames_ok: int = 0
    bad_checksums: int = 0
    resyncs: int = 0
    bytes_skipped: int = 0
    frames_lost: int = 0
    malformed: int = 0
    duplicates: int = 0


class Codec(Protocol):
    stats: CodecStats

    def feed(self, data: bytes, stamp_ns: int) -> list[Any]:
        """Messages completed by ``data``; garbage is counted and skipped, never raised."""
        ...


class Driver(Protocol):
    device: str
    on_raw: RawHook | None

    def open(self) -> None:
        """Connect (and handshake); raises DeviceError with a clear message on failure."""
        ...

    def read(self, timeout_s: float) -> list[Any]:
        """Block at most ``timeout_s``; return decoded messages; reconnects by itself."""
        ...

    def close(self) -> None: ...

    def diagnostics(self, stamp_ns: int) -> DeviceDiagnostics: ...

    # optional: ``fileno() -> int | None``, the descriptor to wait on while the link is up
    # (then ``read(0)`` never blocks); ``buffered() -> bool``, bytes read and not decoded


class LinkDiagnostics:
    """Mixin: ``diagnostics()`` of a driver from its codec's counters and its link state.

    Expects ``device``, ``codec.stats``, ``connected``, ``reconnects``, ``last_error`` and
    ``_last_seen_ns``; the rate is of good frames since the previous report.
    """

    _rate_mark: tuple[float, int] = (0.0, 0)

    def _frames_lost(self, stats: CodecStats) -> int:
        return stats.frames_lost

    def diagnostics(self, stamp_ns: int) -> DeviceDiagnostics:
        s = self.codec.stats  # type: ignore[attr-defined]
        now = time.monotonic()
        t0, n0 = self._rate_mark
        rate = (s.frames_ok - n0) / (now - t0) if t0 and now > t0 else 0.0
        self._rate_mark = (now, s.frames_ok)
        return DeviceDiagnostics(
            stamp_ns=stamp_ns,
            device=self.device,  # type: ignore[attr-defined]
            connected=self.connected,  # type: ignore[attr-defined]
            frames_ok=s.frames_ok,
            bad_checksums=s.bad_checksums,
            resyncs=s.resyncs,
            bytes_skipped=s.bytes_skipped,
            frames_lost=self._frames_lost(s),
            malformed=s.malformed,
            duplicates=s.duplicates,
            reconnects=self.reconnects,  # type: ignore[attr-defined]
            last_seen_ns=self._last_seen_ns,  # type: ignore[attr-defined]
            rate_hz=rate,
            last_error=self.last_error,  # type: ignore[attr-defined]
        )


class DeviceError(OSError):
    """A device cannot be opened or used: the message says which port and what to do."""
