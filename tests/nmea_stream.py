"""A clean NMEA stream for the fuzzer (tests/codec_fuzz.py), made with the project's writer.

Two epochs of GGA, GSA, RMC, VTG, GST and ZDA, a TXT sentence of exactly the maximum
length and a GSV sentence (a type not decoded). NMEA is checked sentence by sentence: a fix
combines the sentences of an epoch, so a lost sentence legitimately changes its epoch's
fix. The whole codec runs (parsers and epoch combiner, and ``flush`` at the end), so an
exception anywhere is caught; the keys are the framer's sentences.
"""

from __future__ import annotations

import datetime as dt
import random
from dataclasses import replace

from drivers.nmea import NmeaCodec, build, xor_checksum
from drivers.nmea.codec import NmeaFramer
from drivers.nmea.sentences import TYPES
from drivers.nmea.writer import epoch_sentences
from msgs import GpsFix
from tests.codec_fuzz import Key, Stream

MAX_LINE = NmeaFramer().max_line

_FIX = GpsFix(0, lat_deg=37.5665, lon_deg=126.978, alt_msl_m=38.5, geoid_sep_m=18.2, mode=3,
              quality=1, satellites=9, hdop=0.9, pdop=1.6, vdop=1.3, speed_mps=1.2,
              course_deg=87.0, std_lat_m=1.1, std_lon_m=1.0, std_alt_m=2.0)  # fmt: skip
SECOND = dt.timedelta(seconds=1)
# Field values a receiver (or a line error that keeps the checksum) may put anywhere.
NASTY = ("", "9999", "235960.00", "240000", "49", "0049", "1899", "2201", "00", "31", "13",
         "-1", "1e400", "nan", "inf", "-0", "0" * 12, "9" * 40, "A", "V", "N", "S", "W", "M",
         ".", "1.2.3", "+5", "12a", "0x1F", "3112", "2902", "290223")  # fmt: skip


class _RecordingFramer(NmeaFramer):
    """The framer, keeping every sentence it passes on (the keys of the NMEA stream)."""

    def __init__(self) -> None:
        super().__init__()
        self.seen: list = []

    def feed(self, data: bytes) -> list:
        out = super().feed(data)
        self.seen += out
        return out


class Nmea(Stream):
    name = "nmea"
    sync = b"$"
    special = b"$*,\r\n0123456789.ABCDEFGNPZ"

    def __init__(self) -> None:
        t0 = dt.datetime(2026, 11, 23, 9, 0, 0, tzinfo=dt.UTC)
        data = b"".join(
            epoch_sentences(replace(_FIX, pdop=1.6 + k, course_deg=87.0 + k), t0 + k * SECOND)
            for k in range(2)
        )
        lines = [line + b"\n" for line in data.split(b"\n") if line]
        body = "GPTXT,01,01,02,"
        lines.insert(3, build(body + "X" * (MAX_LINE - 4 - len(body))))
        lines.insert(9, build("GPGSV,1,1,01,07,45,120,40"))
        self.frames = self._keyed(lines)

    def new(self) -> NmeaCodec:
        codec = NmeaCodec()
        codec.framer = _RecordingFramer()
        codec.stats = codec.framer.stats
        return codec

    def feed(self, codec: NmeaCodec, chunk: bytes, stamp: int) -> list[Key]:
        codec.feed(chunk, stamp)
        seen = codec.framer.seen  # type: ignore[attr-defined]
        codec.framer.seen = []  # type: ignore[attr-defined]
        return seen

    def finish(self, codec: NmeaCodec) -> list[Key]:
        codec.flush()
        return []

    def lengths(self, data: bytes, p: int) -> list[int]:
        end = data.find(b"\n", p)
        return [end - p + 1] if end >= 0 else []

    def valid(self, frame: bytes) -> bool:
        """``$body*HH`` (CR LF optional) of printable ASCII, no longer than the maximum,
        with the XOR of the body; nothing before the ``$``."""
        text = frame.rstrip(b"\r\n")
        star = text.rfind(b"*")
        if not (text[:1] == b"$" and text.rfind(b"$") == 0 and len(text) <= MAX_LINE):
            return False
        if not (text.isascii() and text.decode().isprintable() and star == len(text) - 3):
            return False
        try:
            return int(text[star + 1 :], 16) == xor_checksum(text[1:star])
        except ValueError:
            return False

    def _fields(self, raw: bytes) -> list[str]:
        text = raw.decode("ascii").rstrip("\r\n")
        return text[1 : text.rfind("*")].split(",")

    def field(self, raw: bytes, rng: random.Random) -> bytes:
        parts = self._fields(raw)
        if rng.random() < 0.2:
            parts[0] = parts[0][:2] + rng.choice(TYPES)
        else:
            parts[rng.randrange(1, len(parts))] = rng.choice(NASTY)
        return build(",".join(parts))

    def maxlen(self, raw: bytes, rng: random.Random) -> bytes | None:
        body = ",".join(self._fields(raw))
        pad = MAX_LINE + rng.randrange(2) - 4 - len(body)
        return build(body + "0" * pad) if pad >= 0 else None
