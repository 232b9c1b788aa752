"""ARCOS server packets: standard SIP (0x32/0x33), CONFIG (0x20), ENCODER (0x90).

Field layouts follow ARIA (ArRobot::processMotorPacket, ArRobotConfigPacketReader):
little-endian integers, NUL-terminated strings. Optional trailing fields are present
only if bytes remain, and a short CONFIG packet is tolerated: decoding stops at the
last whole field. Encoders are given too, for the emulated robot.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable

SIP_STOPPED = 0x32
SIP_MOVING = 0x33
CONFIG_ID = 0x20
ENCODER_ID = 0x90
RESET_ID = 0xFF
SYNC_IDS = (0, 1, 2)

# (name, struct code) — "z" marks a NUL-terminated string.
SIP_FIELDS = (
    ("XPOS", "H"),
    ("YPOS", "H"),
    ("THPOS", "h"),
    ("L_VEL", "h"),
    ("R_VEL", "h"),
    ("BATTERY", "B"),
    ("STALL_AND_BUMPERS", "H"),
    ("CONTROL", "h"),
    ("FLAGS", "H"),
    ("COMPASS", "B"),
)
SIP_TRAILING = (
    ("GRIP_STATE", "B"),
    ("ANPORT", "B"),
    ("ANALOG", "B"),
    ("DIGIN", "B"),
    ("DIGOUT", "B"),
    ("BATTERYX10", "H"),
    ("CHARGESTATE", "B"),
    ("ROTVEL", "h"),
    ("FAULTFLAGS", "H"),
)

CONFIG_FIELDS = (
    ("Type", "z"), ("SubType", "z"), ("SerialNumber", "z"), ("FourMotors", "B"),
    ("RotVelTop", "H"), ("TransVelTop", "H"), ("RotAccelTop", "H"), ("TransAccelTop", "H"),
    ("PwmMax", "H"), ("Name", "z"), ("SipCycleTime", "B"), ("HostBaud", "B"),
    ("Aux1Baud", "B"), ("HasGripper", "H"), ("FrontSonar", "H"), ("RearSonar", "B"),
    ("LowBattery", "H"), ("RevCount", "H"), ("Watchdog", "H"), ("NormalMPacs", "B"),
    ("StallVal", "H"), ("StallCount", "H"), ("JoyVel", "H"), ("JoyRotVel", "H"),
    ("RotVelMax", "H"), ("TransVelMax", "H"), ("RotAccel", "H"), ("RotDecel", "H"),
    ("RotKP", "H"), ("RotKV", "H"), ("RotKI", "H"), ("TransAccel", "H"), ("TransDecel", "H"),
    ("TransKP", "H"), ("TransKV", "H"), ("TransKI", "H"), ("FrontBumps", "B"),
    ("RearBumps", "B"), ("HasCharger", "B"), ("SonarCycle", "B"), ("ResetBaud", "B"),
    ("GyroType", "B"), ("DriftFactor", "h"), ("Aux2Baud", "B"), ("Aux3Baud", "B"),
    ("TicksMM", "H"), ("ShutdownVoltage", "H"), ("FirmwareVersion", "z"), ("GyroCW", "H"),
    ("GyroCCW", "H"), ("KinematicsDelay", "B"), ("LatVelTop", "H"), ("LatAccelTop", "H"),
    ("LatVelMax", "H"), ("LatAccel", "H"), ("LatDecel", "H"),
    ("PowerbotChargeThreshold", "H"), ("PDBPort", "B"), ("GyroRateLimit", "H"),
    ("HighTemperatureShutdown", "b"), ("PowerBits", "H"), ("BatteryType", "B"),
    ("StateOfChargeLow", "H"), ("StateOfChargeShutdown", "H"),
    ("FirmwareBootloaderVersion", "z"), ("ConfigFlags", "I"), ("GyroFWVersion", "h"),
)  # fmt: skip


class PacketError(ValueError):
    """A packet that passed its checksum but does not hold what its ID promises."""


def _read_fields(
    data: bytes, fields: Iterable[tuple[str, str]], pos: int, out: dict, tolerant: bool
) -> int:
    for name, code in fields:
        if code == "z":
            end = data.find(b"\x00", pos)
            if end < 0:
                if tolerant:
                    return len(data)
                raise PacketError(f"unterminated string {name}")
            out[name] = data[pos:end].decode("latin-1")
            pos = end + 1
            continue
        size = struct.calcsize("<" + code)
        if pos + size > len(data):
            if tolerant:
                return pos
            raise PacketError(f"packet too short for {name} ({len(data)} bytes)")
        (out[name],) = struct.unpack_from("<" + code, data, pos)
        pos += size
    return pos


def decode_sip(data: bytes) -> dict[str, int]:
    """Every field of a standard SIP by its ARIA name; sonar readings as SONAR_<n>."""
    out: dict[str, int] = {}
    pos = _read_fields(data, SIP_FIELDS, 0, out, tolerant=False)
    if pos >= len(data):
        raise PacketError("SIP without sonar count")
    count = data[pos]
    pos += 1
    out["SONAR_COUNT"] = count
    if pos + 3 * count > len(data):
        raise PacketError(f"SIP too short for {count} sonar readings")
    for _ in range(count):
        num, rng = struct.unpack_from("<BH", data, pos)
        out[f"SONAR_{num}"] = rng
        pos += 3
    _read_fields(data, SIP_TRAILING, pos, out, tolerant=True)
    return out


def encode_sip(fields: dict[str, int], sonars: dict[int, int] | None = None) -> bytes:
    """SIP data (without ID) from fields; trailing fields up to the last one given."""
    parts = [struct.pack("<" + c, int(fields.get(n, 0))) for n, c in SIP_FIELDS]
    sonars = sonars or {}
    parts.append(bytes([len(sonars)]))
    parts += [struct.pack("<BH", n, r) for n, r in sonars.items()]
    present = [i for i, (n, _) in enumerate(SIP_TRAILING) if n in fields]
    if present:
        for n, c in SIP_TRAILING[: present[-1] + 1]:
            parts.append(struct.pack("<" + c, int(fields.get(n, 0))))
    return b"".join(parts)


def decode_config(data: bytes) -> dict[str, int | str]:
    """CONFIG packet fields (a short packet gives the fields it has)."""
    out: dict[str, int | str] = {}
    _read_fields(data, CONFIG_FIELDS, 0, out, tolerant=True)
    return out


def encode_config(values: dict[str, int | str]) -> bytes:
    parts = []
    for name, code in CONFIG_FIELDS:
        v = values.get(name, "" if code == "z" else 0)
        if code == "z":
            parts.append(str(v).encode("latin-1") + b"\x00")
        else:
            parts.append(struct.pack("<" + code, int(v)))
    return b"".join(parts)


def decode_encoder(data: bytes) -> tuple[int, int]:
    """(left, right) raw encoder counts of an ENCODER packet."""
    if len(data) < 8:
        raise PacketError(f"ENCODER packet too short ({len(data)} bytes)")
    return struct.unpack_from("<ii", data, 0)


def encode_encoder(left: int, right: int) -> bytes:
    return struct.pack("<ii", left, right)


def decode_sync2(data: bytes) -> tuple[str, str, str]:
    """(name, class, subclass) of the SYNC2 reply's NUL-terminated strings."""
    parts = data.split(b"\x00")
    parts += [b""] * 3
    return tuple(p.decode("latin-1") for p in parts[:3])  # type: ignore[return-value]


def encode_sync2(name: str, robot_class: str, subclass: str) -> bytes:
    return b"".join(s.encode("latin-1") + b"\x00" for s in (name, robot_class, subclass))
