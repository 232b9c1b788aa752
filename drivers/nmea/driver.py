"""NMEA GPS driver: a receiver streaming sentences on a serial port, TCP, or a log file."""

from __future__ import annotations

from drivers.base import Clock, RawHook, wall_clock_ns
from drivers.nmea.codec import NmeaCodec
from drivers.nmea.local import Datum
from drivers.stream import StreamDriver


class NmeaDriver(StreamDriver):
    """Streams :class:`msgs.GpsFix`, one per epoch. NMEA receivers need no setup."""

    device = "gps"

    def __init__(
        self,
        url: str,
        baud: int = 9600,
        datum: Datum | None = None,
        require_checksum: bool = True,
        clock: Clock = wall_clock_ns,
        on_raw: RawHook | None = None,
        **kw: float,
    ) -> None:
        codec = NmeaCodec(require_checksum=require_checksum, datum=datum)
        super().__init__(url, codec, baud, clock, on_raw, **kw)
