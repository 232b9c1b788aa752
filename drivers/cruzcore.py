"""CruzCore yaw gyro (R1001/R1050/XG1010): 8-byte packets and ASCII commands.

Packet (shared/protocols/sensors.md): ``FF FF | rate int16 LE (0.01 deg/s) | angle int16
LE (0.01 deg, wraps at +-180) | checksum int16 LE = (0xFFFF + rate + angle) mod 65536``.
The codec hunts ``FF FF`` and accepts a frame only if its checksum holds (a rate or angle
byte may be FF, so a false header is skipped one byte at a time). Angles are unwrapped
across +-180 deg so the heading is continuous. Commands are ``$<body>*<hex>`` with the SUM
(mod 256) of the body bytes: ``$MIB,RESET*87`` re-zeroes the angle, ``$MIA,...`` sets baud
and rate (empty fields keep their value). The packet has no sequence number, so a packet
lost on the line cannot be counted (``frames_lost`` stays 0).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from drivers.base import CodecStats
from msgs import GyroSample

HEADER = b"\xff\xff"
PACKET_LEN = 8
RATE_LSB_DEGPS = 0.01
ANGLE_LSB_DEG = 0.01
DEG = math.pi / 180.0
_PACK = struct.Struct("<2shhH")


def checksum(rate_raw: int, angle_raw: int) -> int:
    """Checksum word of a packet: (0xFFFF + rate + angle) mod 65536, on signed values."""
    return (0xFFFF + rate_raw + angle_raw) & 0xFFFF


def encode_packet(rate_radps: float, angle_rad: float) -> bytes:
    """One packet for a rate (rad/s) and angle (rad, wrapped into +-180 deg)."""
    rate_raw = _clip16(round(rate_radps / DEG / RATE_LSB_DEGPS))
    angle_deg = math.remainder(angle_rad / DEG, 360.0)
    angle_raw = _clip16(round(angle_deg / ANGLE_LSB_DEG))
    if angle_raw == -18000:
        angle_raw = 18000
    return _PACK.pack(HEADER, rate_raw, angle_raw, checksum(rate_raw, angle_raw))


def _clip16(v: int) -> int:
    return max(-32768, min(32767, int(v)))


# ------------------------------------------------------------------ commands


def sum_checksum(body: str) -> int:
    return sum(body.encode("ascii")) & 0xFF


def command(body: str) -> bytes:
    """``$<body>*HH\\r\\n`` with the SUM checksum of the body."""
    return f"${body}*{sum_checksum(body):02X}\r\n".encode("ascii")


def reset_command() -> bytes:
    return command("MIB,RESET")


def config_command(baud: int | None = None, rate_hz: int | None = None) -> bytes:
    """``$MIA,I,B,<baud>,R,<rate>,D,Y,N``; ``None`` leaves the field empty (keep value)."""
    b = "" if baud is None else str(int(baud))
    r = "" if rate_hz is None else str(int(rate_hz))
    if baud is None and rate_hz is None:
        return command("MIA,,,,,,,,")
    if baud is None:
        return command(f"MIA,,,,R,{r},,,")
    return command(f"MIA,I,B,{b},R,{r},D,Y,N")


@dataclass(frozen=True)
class GyroCommand:
    """A parsed command: ``reset`` or ``config`` (baud/rate None = keep)."""

    kind: str
    baud: int | None = None
    rate_hz: int | None = None


def parse_command(line: bytes) -> GyroCommand | None:
    """Parse one command line; None when malformed or the checksum is wrong."""
    try:
        text = line.decode("ascii").strip()
    except UnicodeDecodeError:
        return None
    if not text.startswith("$") or "*" not in text:
        return None
    body, _, hh = text[1:].rpartition("*")
    try:
        if int(hh, 16) != sum_checksum(body):
            return None
    except ValueError:
        return None
    fields = body.split(",")
    if fields[0] == "MIB" and len(fields) >= 2 and fields[1] == "RESET":
        return GyroCommand("reset")
    if fields[0] == "MIA":
        # positional: MIA,I,B,<baud>,R,<rate>,D,Y,N (empty = keep)
        fields += [""] * (9 - len(fields))
        return GyroCommand("config", _int_or_none(fields[3]), _int_or_none(fields[5]))
    return None


def _int_or_none(s: str) -> int | None:
    try:
        return int(s)
    except ValueError:
        return None


class CommandParser:
    """Splits a byte stream into command lines (for the fake); garbage is counted.

    A command ends at LF, or at the ``$`` of the next command when its LF was lost, so a
    command without its line end costs at most itself, never the command after it.
    """

    MAX_LINE = 80

    def __init__(self) -> None:
        self._buf = bytearray()
        self.stats = CodecStats()

    def feed(self, data: bytes) -> list[GyroCommand]:
        self._buf += data
        out: list[GyroCommand] = []
        while True:
            start = self._buf.find(b"$")
            if start < 0:
                self.stats.bytes_skipped += len(self._buf)
                self._buf.clear()
                break
            if start:
                self.stats.bytes_skipped += start
                del self._buf[:start]
            end = self._buf.find(b"\n")
            nxt = self._buf.find(b"$", 1)
            if nxt >= 0 and (end < 0 or nxt < end):
                end = nxt - 1  # its LF was lost: the next command starts here
            elif end < 0:
                if len(self._buf) > self.MAX_LINE:
                    self.stats.bytes_skipped += 1
                    del self._buf[:1]
                    continue
                break
            line = bytes(self._buf[: end + 1])
            del self._buf[: end + 1]
            cmd = parse_command(line)
            if cmd is None:
                self.stats.bad_checksums += 1
            else:
                self.stats.frames_ok += 1
                out.append(cmd)
        return out


# ------------------------------------------------------------------ codec


class CruzCoreCodec:
    """Bytes -> :class:`msgs.GyroSample` with resync and angle unwrapping.

    The packet carries no time, so a sample is stamped with the time of the read that
    brought it. With ``rate_hz`` (the rate the gyro was set to), several packets of one
    read (a USB adapter's burst, a reader that reads at its own pace) are stamped back
    from it one period apart: the last with the read's time, each earlier one a period
    before the next, as the gyro sent them; never at or before the previous read's last
    sample (then spread evenly between the two). Without it, all share the read's time."""

    def __init__(self, rate_hz: float | None = None) -> None:
        self.stats = CodecStats()
        self._buf = bytearray()
        self._last_wrapped: float | None = None
        self._turns = 0
        self.period_ns = 0
        self._last_stamp: int | None = None
        self.set_rate(rate_hz)

    def set_rate(self, rate_hz: float | None) -> None:
        """The rate the gyro sends at (None: unknown, a read's packets share its time)."""
        self.period_ns = int(1e9 / rate_hz) if rate_hz else 0

    def reset_unwrap(self) -> None:
        """Forget the unwrapping state (after a ``$MIB,RESET``)."""
        self._last_wrapped = None
        self._turns = 0

    def feed(self, data: bytes, stamp_ns: int) -> list[GyroSample]:
        buf = self._buf
        buf += data
        out: list[GyroSample] = []
        i = 0
        n = len(buf)
        skipped_run = False
        while n - i >= PACKET_LEN:
            if buf[i] != 0xFF or buf[i + 1] != 0xFF:
                j = buf.find(HEADER, i + 1)
                if j < 0:
                    # keep a trailing FF: it may start the next header
                    j = n - 1 if buf[n - 1] == 0xFF else n
                self.stats.bytes_skipped += j - i
                if not skipped_run:
                    self.stats.resyncs += 1
                    skipped_run = True
                i = j
                continue
            _, rate_raw, angle_raw, ck = _PACK.unpack_from(buf, i)
            if ck != checksum(rate_raw, angle_raw) or not -18000 <= angle_raw <= 18000:
                self.stats.bad_checksums += 1
                self.stats.bytes_skipped += 1
                if not skipped_run:
                    self.stats.resyncs += 1
                    skipped_run = True
                i += 1
                continue
            skipped_run = False
            i += PACKET_LEN
            self.stats.frames_ok += 1
            out.append(self._sample(rate_raw, angle_raw, stamp_ns))
        if len(out) > 1 and self.period_ns:
            out = self._stamped_back(out, stamp_ns)
        if out:
            self._last_stamp = out[-1].stamp_ns
        if i:
            del buf[:i]
        if len(buf) < PACKET_LEN and buf and buf[0] != 0xFF:
            j = buf.find(b"\xff")
            j = len(buf) if j < 0 else j
            self.stats.bytes_skipped += j
            del buf[:j]
        return out

    def _stamped_back(self, out: list[GyroSample], stamp_ns: int) -> list[GyroSample]:
        """The samples of one read stamped back from it (class docstring)."""
        n, period, last = len(out), self.period_ns, self._last_stamp
        first = stamp_ns - (n - 1) * period
        if last is None or first > last:
            stamps = [first + k * period for k in range(n)]
        elif stamp_ns - last >= n:
            stamps = [last + (k + 1) * (stamp_ns - last) // n for k in range(n)]
        else:  # no room after the last (the clock went back): the read's time, as without
            return out
        return [
            GyroSample(t, g.rate_radps, g.angle_rad, g.angle_wrapped_rad)
            for t, g in zip(stamps, out, strict=True)
        ]

    def _sample(self, rate_raw: int, angle_raw: int, stamp_ns: int) -> GyroSample:
        wrapped = angle_raw * ANGLE_LSB_DEG * DEG
        if self._last_wrapped is not None:
            d = wrapped - self._last_wrapped
            if d > math.pi:
                self._turns -= 1
            elif d < -math.pi:
                self._turns += 1
        self._last_wrapped = wrapped
        return GyroSample(
            stamp_ns=stamp_ns,
            rate_radps=rate_raw * RATE_LSB_DEGPS * DEG,
            angle_rad=wrapped + 2.0 * math.pi * self._turns,
            angle_wrapped_rad=wrapped,
        )
