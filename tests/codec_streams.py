"""Clean frame streams of every codec, made with the project's own encoders, for the fuzzer.

One adapter per codec (tests/codec_fuzz.py says what an adapter offers): ARCOS (SIPs,
CONFIG, a SYNC2 reply, an ENCODER packet), the IR board on serial (with a foreign board's
frame and a command frame among the samples) and on CAN (logged frames, with a foreign and
an extended frame) and the CruzCore gyro; NMEA's is in tests/nmea_stream.py, the fakes'
command parsers' in tests/command_streams.py. ``valid`` says whether bytes are a frame
passing the protocol's checks, by re-encoding them with the project's encoders.
Each message is reduced to a key that does not depend on earlier frames (odometry is
integrated, so a SIP's key is its raw fields); the keys of a clean stream all differ.
"""

from __future__ import annotations

import random
import struct
from typing import Any

from drivers.arcos import ArcosCodec, frame
from drivers.arcos.packet import MAX_COUNT
from drivers.arcos.packets import (
    CONFIG_ID,
    ENCODER_ID,
    SIP_FIELDS,
    SIP_MOVING,
    SIP_STOPPED,
    SIP_TRAILING,
    decode_sip,
    encode_config,
    encode_encoder,
    encode_sip,
    encode_sync2,
)
from drivers.cruzcore import HEADER, CruzCoreCodec, checksum, encode_packet
from drivers.irboard import IrCanCodec, IrSerialCodec, RawSample, crc16_ccitt, encode_sample
from drivers.irboard.canframe import pack_raw_frame, pack_sample
from drivers.irboard.serialframe import SYNC_DATA, encode_command
from msgs import RobotInfo, RobotOdometry
from tests.codec_fuzz import Key, Stream, random_bytes
from tests.nmea_stream import Nmea

_RANGES = {"H": (0, 0xFFFF), "h": (-0x8000, 0x7FFF), "B": (0, 0xFF)}


# ------------------------------------------------------------------ ARCOS


class Arcos(Stream):
    name = "arcos"
    codec_type = ArcosCodec
    sync = b"\xfa\xfb"
    special = b"\xfa\xfb\x03\x32\x33\x00\xff"

    def __init__(self) -> None:
        frames = [frame(2, encode_sync2("hilnav-fake", "Pioneer", "p3dx-sh"))]
        for k in range(8):
            f = {"XPOS": 1000 + 37 * k, "YPOS": 2000 - 11 * k, "THPOS": 100 + 5 * k,
                 "L_VEL": 120 + k, "R_VEL": 130, "BATTERY": 125, "FLAGS": 1}  # fmt: skip
            if k % 3 == 1:
                f.update(BATTERYX10=128, ROTVEL=10 + k, FAULTFLAGS=0)
            sonars = {0: 500 + k, 3: 1200} if k % 2 else None
            frames.append(frame(SIP_MOVING if k % 2 else SIP_STOPPED, encode_sip(f, sonars)))
        frames.insert(3, frame(CONFIG_ID, encode_config({"Type": "Pioneer", "Name": "fz"})))
        frames.insert(6, frame(ENCODER_ID, encode_encoder(5, -7)))
        self.frames = self._keyed(frames)

    def key(self, m: Any) -> Key:
        if isinstance(m, RobotOdometry):  # the pose integrates earlier SIPs: raw fields
            return ("sip", m.moving, tuple(sorted(m.raw.items())))
        if isinstance(m, RobotInfo):
            return ("config", tuple(sorted(m.config.items())))
        return ("packet", m.packet_id, m.data)

    def lengths(self, data: bytes, p: int) -> list[int]:
        return [3 + data[p + 2]] if p + 2 < len(data) else []

    def valid(self, raw: bytes) -> bool:
        return 5 <= len(raw) <= 3 + MAX_COUNT and frame(raw[3], raw[4:-2]) == raw

    def field(self, raw: bytes, rng: random.Random) -> bytes | None:
        pid, body = raw[3], raw[4:-2]
        how = rng.randrange(4)
        if how == 0 and pid in (SIP_STOPPED, SIP_MOVING):
            sip = decode_sip(body)
            name, code = rng.choice(SIP_FIELDS + SIP_TRAILING[:1])
            lo, hi = _RANGES[code]
            sip[name] = rng.choice((lo, hi, rng.randint(lo, hi)))
            sonars = {int(k[6:]): v for k, v in sip.items() if k[6:].isdigit()}
            return frame(pid, encode_sip(sip, sonars))
        if how == 1:
            return frame(rng.randrange(256), body)
        if how == 2:
            room = MAX_COUNT - 3 - len(body)
            return frame(pid, body + random_bytes(rng, rng.randint(min(1, room), room)))
        return frame(pid, body[: rng.randrange(len(body) + 1)])

    def maxlen(self, raw: bytes, rng: random.Random) -> bytes:
        count = rng.choice((MAX_COUNT, 0xFF, rng.randint(3, 0xFF)))
        return raw[:2] + bytes([count]) + raw[3:]


# ------------------------------------------------------------------ IR board, serial


def _ir_frame(board: int, seq: int, bits: int, counts: list[int]) -> bytes:
    """A data frame with a right CRC whatever its content (encode_sample checks it)."""
    body = struct.pack("<BHBB", board, seq, len(counts), bits)
    body += struct.pack(f"<{len(counts)}H", *counts)
    return SYNC_DATA + body + crc16_ccitt(body).to_bytes(2, "big")


def _ir_key(s: Any) -> Key:
    return (s.board_id, s.seq, s.raw_counts)


class IrSerial(Stream):
    name = "ir_serial"
    codec_type = IrSerialCodec
    key = staticmethod(_ir_key)
    sync = SYNC_DATA
    special = b"\xa5\x5a\xc3\x06\x08\x0a\x0c"

    def __init__(self) -> None:
        frames = [encode_sample(RawSample(1, (65530 + k) & 0xFFFF, 10, tuple(_counts(k, 6))))
                  for k in range(10)]  # fmt: skip
        frames.insert(4, encode_sample(RawSample(2, 7, 12, (4000, 1, 2))))  # another board
        frames.insert(8, encode_command(1, 1, (20).to_bytes(2, "little")))  # not a sample
        self.frames = self._keyed(frames)

    def lengths(self, data: bytes, p: int) -> list[int]:
        return [9 + 2 * n for n in range(1, 9)]

    def valid(self, raw: bytes) -> bool:
        """Right CRC, 1-8 channels, 10 or 12 bits, every count below 2^bits."""
        if len(raw) < 11 or raw[:2] != SYNC_DATA or len(raw) != 9 + 2 * raw[5]:
            return False
        board, seq, n, bits = struct.unpack_from("<BHBB", raw, 2)
        counts = list(struct.unpack_from(f"<{n}H", raw, 7))
        plausible = 1 <= n <= 8 and bits in (10, 12) and max(counts) < 1 << bits
        return plausible and _ir_frame(board, seq, bits, counts) == raw

    def field(self, raw: bytes, rng: random.Random) -> bytes | None:
        if raw[:2] != SYNC_DATA:
            return None
        board, seq, n, bits = struct.unpack_from("<BHBB", raw, 2)
        counts = list(struct.unpack_from(f"<{n}H", raw, 7))
        how = rng.randrange(4)
        if how == 0:
            seq = rng.getrandbits(16)
        elif how == 1:
            counts[rng.randrange(n)] = rng.choice((1023, 1024, 4095, rng.getrandbits(16)))
        elif how == 2:
            board, bits = rng.choice((1, 2, rng.getrandbits(8))), rng.choice((10, 12, 11))
        else:
            counts = counts[: rng.randint(1, n)] + [rng.randrange(1024)] * rng.randint(0, 8 - n)
        return _ir_frame(board, seq, bits, counts)

    def maxlen(self, raw: bytes, rng: random.Random) -> bytes | None:
        if raw[:2] != SYNC_DATA:
            return None
        if rng.random() < 0.5:  # the channel count maxed, CRC left as it was
            return raw[:5] + b"\x08" + raw[6:]
        board, seq = struct.unpack_from("<BH", raw, 2)
        return _ir_frame(board, seq, 10, [rng.randrange(1024) for _ in range(8)])


def _counts(k: int, n: int) -> list[int]:
    return [(100 + 53 * k + 97 * ch) % 1024 for ch in range(n)]


# ------------------------------------------------------------------ IR board, CAN


class IrCan(Stream):
    name = "ir_can"
    codec_type = IrCanCodec
    key = staticmethod(_ir_key)
    framed = True
    special = b"\x00\x03\x01\xff"

    def __init__(self) -> None:
        frames = [pack_raw_frame(*pack_sample(RawSample(1, k, 10, tuple(_counts(k, 6)))))
                  for k in range(12)]  # fmt: skip
        frames.insert(3, pack_raw_frame(0x123, b"\x01\x02"))
        frames.insert(7, pack_raw_frame(0x301, bytes(8), is_extended=True))
        self.frames = self._keyed(frames)

    def lengths(self, data: bytes, p: int) -> list[int]:
        return []

    def valid(self, raw: bytes) -> bool:
        return True  # CAN checks its own CRC: any frame that arrives is as sent

    def garbage(self, rng: random.Random) -> list[bytes]:
        out = []
        for _ in range(rng.randint(1, 4)):
            arb = rng.choice((0x301, 0x301, rng.randrange(0x800), rng.getrandbits(29)))
            n = rng.choice((rng.randint(0, 8), rng.randint(0, 70)))
            raw = pack_raw_frame(arb, random_bytes(rng, n), rng.random() < 0.2)
            out.append(raw[: rng.randrange(4)] if rng.random() < 0.1 else raw)
        return out

    def field(self, raw: bytes, rng: random.Random) -> bytes:
        counts = tuple(rng.choice((0, 1023, rng.randrange(1024))) for _ in range(6))
        return pack_raw_frame(*pack_sample(RawSample(1, rng.randrange(16), 10, counts)))

    def maxlen(self, raw: bytes, rng: random.Random) -> bytes:
        return raw + bytes(rng.choice((64, 65)) - (len(raw) - 4))


# ------------------------------------------------------------------ CruzCore gyro


class Gyro(Stream):
    name = "cruzcore"
    codec_type = CruzCoreCodec
    sync = HEADER
    special = b"\xff\xff\x00"

    def __init__(self) -> None:
        frames = [encode_packet(0.1 + 0.05 * k, -3.0 + 0.55 * k) for k in range(12)]
        self.frames = self._keyed(frames)

    def key(self, m: Any) -> Key:
        return (m.rate_radps, m.angle_wrapped_rad)  # the unwrapped angle depends on history

    def lengths(self, data: bytes, p: int) -> list[int]:
        return [8]

    def valid(self, raw: bytes) -> bool:
        if len(raw) != 8:
            return False
        _, rate, angle, _ = struct.unpack("<2shhH", raw)
        return -18000 <= angle <= 18000 and _gyro_packet(rate, angle) == raw

    def field(self, raw: bytes, rng: random.Random) -> bytes:
        return _gyro_packet(rng.getrandbits(16) - 0x8000, rng.randint(-18000, 18000))

    def maxlen(self, raw: bytes, rng: random.Random) -> bytes:
        extremes = (-0x8000, 0x7FFF, 18000, -18000, 18001, -18001)
        return _gyro_packet(rng.choice(extremes), rng.choice(extremes))


def _gyro_packet(rate: int, angle: int) -> bytes:
    return struct.pack("<2shhH", HEADER, rate, angle, checksum(rate, angle))


STREAMS: dict[str, type[Stream]] = {a.name: a for a in (Arcos, IrSerial, IrCan, Gyro, Nmea)}
