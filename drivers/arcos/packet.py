"""ARCOS packet framing: ``FA FB COUNT ID data... CHK_HI CHK_LO`` with resync.

COUNT counts the bytes after it (ID, data and the two checksum bytes). The checksum
(ARIA ArRobotPacket::calcCheckSum) sums successive byte pairs of ID..data as big-endian
16-bit words, keeping 16 bits; an odd last byte is XORed into the low byte. It is sent
high byte first. The parser hunts FA then FB, drops a packet with a bad checksum, and
like ARIA's ArRobotPacketReceiver drops a partial packet whose bytes arrive more than
100 ms apart; every byte it cannot use is counted.

A corrupted COUNT would make it wait for bytes that belong to the next packets (up to 252
bytes, nine SIPs at 9600 baud). So while a packet is incomplete, the parser looks for a
later header inside it that starts a complete packet with a good checksum: if there is
one, the pending packet was bogus and the parser skips to it (a resync), so each packet is
returned by the ``feed`` that completes it. ARCOS packets carry no sequence number: a
packet lost on the line cannot be counted (``frames_lost`` stays 0).
"""

from __future__ import annotations

from dataclasses import dataclass

from drivers.base import CodecStats

SYNC = b"\xfa\xfb"
MAX_COUNT = 249  # ARIA's receive buffer; real packets stay near 200 bytes
INTER_BYTE_TIMEOUT_NS = 100_000_000


def checksum(body: bytes) -> int:
    """ARCOS checksum over ID + data."""
    c = 0
    n = len(body)
    i = 0
    while n > 1:
        c += (body[i] << 8) | body[i + 1]
        c &= 0xFFFF
        n -= 2
        i += 2
    if n > 0:
        c ^= body[i]
    return c


def frame(packet_id: int, data: bytes = b"") -> bytes:
    """A whole packet on the wire for ``packet_id`` and ``data``."""
    body = bytes([packet_id & 0xFF]) + data
    if len(body) + 2 > MAX_COUNT:
        raise ValueError(f"ARCOS packet too long: {len(body) + 2} > {MAX_COUNT}")
    c = checksum(body)
    return SYNC + bytes([len(body) + 2]) + body + bytes([c >> 8, c & 0xFF])


@dataclass(frozen=True, slots=True)
class ArcosPacket:
    """One checked packet: its ID, its data (without ID and checksum), arrival stamp."""

    packet_id: int
    data: bytes
    stamp_ns: int


class PacketParser:
    """Incremental, garbage-tolerant packet parser (pure; stamps come with the bytes)."""

    def __init__(self, inter_byte_timeout_ns: int = INTER_BYTE_TIMEOUT_NS) -> None:
        self.stats = CodecStats()
        self._buf = bytearray()
        self._last_ns: int | None = None
        self._timeout = inter_byte_timeout_ns

    def feed(self, data: bytes, stamp_ns: int) -> list[ArcosPacket]:
        if (
            self._buf
            and self._last_ns is not None
            and stamp_ns - self._last_ns > self._timeout
            and self._timeout > 0
        ):
            # Stale partial packet: ARIA gives up on it.
            self.stats.bytes_skipped += len(self._buf)
            self.stats.resyncs += 1
            self._buf.clear()
        self._last_ns = stamp_ns
        self._buf += data
        out: list[ArcosPacket] = []
        buf = self._buf
        while True:
            start = buf.find(SYNC)
            if start < 0:
                # Keep a trailing FA: it may start the next packet.
                keep = 1 if buf[-1:] == b"\xfa" else 0
                skipped = len(buf) - keep
                if skipped:
                    self.stats.bytes_skipped += skipped
                    self.stats.resyncs += 1
                    del buf[:skipped]
                break
            if start:
                self.stats.bytes_skipped += start
                self.stats.resyncs += 1
                del buf[:start]
            if len(buf) < 3:
                break
            count = buf[2]
            if count < 3 or count > MAX_COUNT:
                self.stats.bytes_skipped += 2
                self.stats.resyncs += 1
                del buf[:2]
                continue
            if len(buf) < 3 + count:
                j = _later_packet(buf)
                if j < 0:
                    break  # wait for the rest of the packet
                self.stats.bytes_skipped += j  # the pending COUNT was bogus
                self.stats.resyncs += 1
                del buf[:j]
                continue
            body = bytes(buf[3 : 3 + count - 2])
            got = (buf[3 + count - 2] << 8) | buf[3 + count - 1]
            if checksum(body) != got:
                self.stats.bad_checksums += 1
                self.stats.bytes_skipped += 2
                del buf[:2]  # resync inside the bad packet: a real one may start there
                continue
            del buf[: 3 + count]
            self.stats.frames_ok += 1
            out.append(ArcosPacket(body[0], body[1:], stamp_ns))
        return out


def _later_packet(buf: bytearray) -> int:
    """Start of the first complete packet with a good checksum after the pending one's
    header (``buf`` starts with a header), or -1."""
    j = buf.find(SYNC, 2)
    n = len(buf)
    while j >= 0 and j + 3 <= n:
        count = buf[j + 2]
        end = j + 3 + count
        good = 3 <= count <= MAX_COUNT and end <= n
        if good and checksum(bytes(buf[j + 3 : end - 2])) == (buf[end - 2] << 8) | buf[end - 1]:
            return j
        j = buf.find(SYNC, j + 1)
    return -1
