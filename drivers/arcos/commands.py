"""ARCOS client commands (ARIA ArCommands.h) and their argument encoding.

A command is a packet whose ID is the command number, followed by an optional
argument: 0x3B + uint16 LE for a non-negative int, 0x1B + magnitude uint16 LE for a
negative int, 0x2B + length byte + bytes for a string.
"""

from __future__ import annotations

from enum import IntEnum

from drivers.arcos.packet import frame

ARG_INT = 0x3B
ARG_NINT = 0x1B
ARG_STR = 0x2B


class Cmd(IntEnum):
    PULSE = 0
    SYNC0 = 0
    OPEN = 1
    SYNC1 = 1
    CLOSE = 2
    SYNC2 = 2
    POLLING = 3
    ENABLE = 4
    SETA = 5
    SETV = 6
    SETO = 7
    MOVE = 8
    ROTATE = 9
    SETRV = 10
    VEL = 11
    HEAD = 12
    DHEAD = 13
    CONFIG = 18
    ENCODER = 19
    RVEL = 21
    SETRA = 23
    SONAR = 28
    STOP = 29
    VEL2 = 32
    IOREQUEST = 40
    BUMPSTALL = 44
    HOSTBAUD = 50
    ESTOP = 55
    BATTERYINFO = 62


HOSTBAUD_CODES = {9600: 0, 19200: 1, 38400: 2, 57600: 3, 115200: 4}
VEL2_DIVISOR_MMPS = 20


def encode_command(cmd: int, arg: int | str | bytes | None = None) -> bytes:
    """The packet bytes of a command with an optional int or string argument."""
    if arg is None:
        return frame(int(cmd))
    if isinstance(arg, str | bytes):
        raw = arg.encode("latin-1") if isinstance(arg, str) else arg
        if len(raw) > 200:
            raise ValueError("ARCOS string argument longer than 200 bytes")
        return frame(int(cmd), bytes([ARG_STR, len(raw)]) + raw)
    value = int(arg)
    if not -0xFFFF <= value <= 0xFFFF:
        raise ValueError(f"ARCOS int argument out of range: {value}")
    if value >= 0:
        return frame(int(cmd), bytes([ARG_INT, value & 0xFF, value >> 8]))
    mag = -value
    return frame(int(cmd), bytes([ARG_NINT, mag & 0xFF, mag >> 8]))


def decode_argument(data: bytes) -> int | bytes | None:
    """The argument of a received command packet (for the emulated robot)."""
    if not data:
        return None
    kind = data[0]
    if kind in (ARG_INT, ARG_NINT) and len(data) >= 3:
        mag = data[1] | (data[2] << 8)
        return mag if kind == ARG_INT else -mag
    if kind == ARG_STR and len(data) >= 2:
        return bytes(data[2 : 2 + data[1]])
    raise ValueError(f"bad ARCOS argument bytes {data.hex()}")


def vel2_argument(left_mmps: float, right_mmps: float, divisor: int = VEL2_DIVISOR_MMPS) -> int:
    """VEL2's packed argument: high byte left, low byte right, signed, in divisor units."""

    def sbyte(v: float) -> int:
        q = int(round(v / divisor))
        return max(-128, min(127, q)) & 0xFF

    raw = (sbyte(left_mmps) << 8) | sbyte(right_mmps)
    return raw - 0x10000 if raw & 0x8000 else raw  # ARIA sends it as a signed short


def split_vel2(arg: int, divisor: int = VEL2_DIVISOR_MMPS) -> tuple[int, int]:
    """(left, right) mm/s from a VEL2 argument as the robot decodes it."""
    raw = arg & 0xFFFF
    hi, lo = raw >> 8, raw & 0xFF
    to_s = lambda b: b - 256 if b > 127 else b  # noqa: E731
    return to_s(hi) * divisor, to_s(lo) * divisor
