"""hilnav IR ADC board, serial framing (docs/protocols/irboard.md).

Data frame, board -> host (9 + 2n bytes, n = 1..8 channels)::

    A5 5A | board u8 | seq u16 LE | n u8 | bits u8 (10|12) | n x counts u16 LE | CRC u16 BE

Command frame, host -> board::

    A5 C3 | board u8 | cmd u8 | len u8 | payload (len bytes) | CRC u16 BE

The CRC is CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over everything after the two
sync bytes. Commands: 0x01 SET_RATE (payload u16 LE, Hz, 1..1000). The codec hunts the
sync word, checks the header's plausibility (n in 1..8, bits 10 or 12, counts < 2^bits)
and the CRC, and on any failure moves on by one byte: it is back in step within one frame.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from drivers.base import CodecStats

SYNC_DATA = b"\xa5\x5a"
SYNC_CMD = b"\xa5\xc3"
MAX_CHANNELS = 8
CMD_SET_RATE = 0x01
_HDR = struct.Struct("<BHBB")  # board, seq, n, bits


def _crc_table() -> tuple[int, ...]:
    table = []
    for i in range(256):
        c = i << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x1021) if c & 0x8000 else (c << 1)
        table.append(c & 0xFFFF)
    return tuple(table)


_TABLE = _crc_table()


def crc16_ccitt(data: bytes | bytearray | memoryview, crc: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final xor."""
    t = _TABLE
    for b in data:
        crc = ((crc << 8) & 0xFFFF) ^ t[(crc >> 8) ^ b]
    return crc


@dataclass(frozen=True, slots=True)
class RawSample:
    """One board sample before conversion: raw ADC counts of each channel."""

    board_id: int
    seq: int
    adc_bits: int
    counts: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class BoardCommand:
    board_id: int
    cmd: int
    payload: bytes

    @property
    def rate_hz(self) -> int | None:
        if self.cmd == CMD_SET_RATE and len(self.payload) == 2:
            return int.from_bytes(self.payload, "little")
        return None


def encode_sample(s: RawSample) -> bytes:
    n = len(s.counts)
    if not 1 <= n <= MAX_CHANNELS:
        raise ValueError(f"an IR board frame carries 1..{MAX_CHANNELS} channels, not {n}")
    if s.adc_bits not in (10, 12):
        raise ValueError(f"adc_bits must be 10 or 12, not {s.adc_bits}")
    body = _HDR.pack(s.board_id & 0xFF, s.seq & 0xFFFF, n, s.adc_bits) + struct.pack(
        f"<{n}H", *s.counts
    )
    return SYNC_DATA + body + crc16_ccitt(body).to_bytes(2, "big")


def encode_command(board_id: int, cmd: int, payload: bytes = b"") -> bytes:
    body = bytes((board_id & 0xFF, cmd & 0xFF, len(payload))) + payload
    return SYNC_CMD + body + crc16_ccitt(body).to_bytes(2, "big")


def set_rate_command(board_id: int, rate_hz: int) -> bytes:
    if not 1 <= rate_hz <= 1000:
        raise ValueError(f"IR board sample rate must be 1..1000 Hz, not {rate_hz}")
    return encode_command(board_id, CMD_SET_RATE, int(rate_hz).to_bytes(2, "little"))


class SerialFrameDecoder:
    """Bytes -> :class:`RawSample` (data frames) or :class:`BoardCommand` (``commands=True``).

    A header whose frame is still incomplete is waited for, unless a complete frame with a
    good CRC already starts inside it: then the header was bogus (a corrupted length or
    channel count) and the decoder skips to that frame rather than hold it back. A data
    frame repeating the previous one of its board (same sequence number and counts) is a
    duplicate: counted in ``duplicates`` and dropped; sequence gaps count ``frames_lost``.
    """

    def __init__(self, commands: bool = False) -> None:
        self.stats = CodecStats()
        self._buf = bytearray()
        self._sync = SYNC_CMD if commands else SYNC_DATA
        self._commands = commands
        self._last: dict[int, tuple[int, tuple[int, ...]]] = {}

    def feed(self, data: bytes) -> list:
        buf = self._buf
        buf += data
        out: list = []
        i = 0
        n = len(buf)
        sync = self._sync
        in_skip = False
        while n - i >= 2:
            if buf[i] != sync[0] or buf[i + 1] != sync[1]:
                j = buf.find(sync, i + 1)
                if j < 0:
                    j = n - 1 if buf[n - 1] == sync[0] else n
                in_skip = self._skip(j - i, in_skip)
                i = j
                continue
            size = self._frame_size(buf, i, n)
            if size == 0:  # need more bytes
                break
            if size > n - i:
                j = self._later_frame(buf, i, n)
                if j < 0:  # wait for the rest of the frame
                    break
                in_skip = self._skip(j - i, in_skip)  # the pending header was bogus
                i = j
                continue
            if size > 0:
                msg = self._checked(buf, i, size)
                if msg is not None:
                    if self._keep(msg):
                        out.append(msg)
                    in_skip = False
                    i += size
                    continue
                self.stats.bad_checksums += 1
            # implausible header or bad CRC: step over one byte and hunt again
            in_skip = self._skip(1, in_skip)
            i += 1
        if i:
            del buf[:i]
        return out

    def _skip(self, count: int, in_skip: bool) -> bool:
        """Count ``count`` skipped bytes (and a resync when a skipped run starts)."""
        self.stats.bytes_skipped += count
        if not in_skip:
            self.stats.resyncs += 1
        return True

    def _frame_size(self, buf: bytearray, i: int, n: int) -> int:
        """Total length the header at ``i`` announces (the frame may still be incomplete);
        0 if the header itself is incomplete, -1 if it is implausible."""
        if self._commands:
            if n - i < 5:
                return 0
            return 7 + buf[i + 4] if buf[i + 4] <= 16 else -1
        if n - i < 7:
            return 0
        ch, bits = buf[i + 5], buf[i + 6]
        if not 1 <= ch <= MAX_CHANNELS or bits not in (10, 12):
            return -1
        return 9 + 2 * ch

    def _later_frame(self, buf: bytearray, i: int, n: int) -> int:
        """Start of the first complete, good frame after ``i`` (inside the pending one), or -1."""
        j = buf.find(self._sync, i + 1)
        while j >= 0:
            size = self._frame_size(buf, j, n)
            if 0 < size <= n - j and self._checked(buf, j, size) is not None:
                return j
            j = buf.find(self._sync, j + 1)
        return -1

    def _checked(self, buf: bytearray, i: int, size: int) -> RawSample | BoardCommand | None:
        """The message of the complete frame at ``i`` if its CRC and content hold, else None."""
        frame = bytes(buf[i + 2 : i + size])
        if crc16_ccitt(frame[:-2]) != int.from_bytes(frame[-2:], "big"):
            return None
        if self._commands:
            return BoardCommand(frame[0], frame[1], frame[3 : 3 + frame[2]])
        board, seq, ch, bits = _HDR.unpack_from(frame)
        counts = struct.unpack_from(f"<{ch}H", frame, _HDR.size)
        if max(counts) >= 1 << bits:
            return None
        return RawSample(board, seq, bits, counts)

    def _keep(self, msg: RawSample | BoardCommand) -> bool:
        """Count a good frame: sequence gaps, duplicates (dropped: False)."""
        if isinstance(msg, RawSample):
            last = self._last.get(msg.board_id)
            if last == (msg.seq, msg.counts):
                self.stats.duplicates += 1
                return False
            if last is not None:
                gap = (msg.seq - last[0] - 1) & 0xFFFF
                if gap < 0x8000:
                    self.stats.frames_lost += gap
            self._last[msg.board_id] = (msg.seq, msg.counts)
        self.stats.frames_ok += 1
        return True
