"""NMEA 0183 sentences: the checked sentence, the XOR checksum, and the field formats the
writers use.

A sentence is ``$<talker><type>,f1,f2,...*HH`` where HH is the XOR of the bytes between
``$`` and ``*``; a proprietary one is ``$P<maker><type>,...``. The fields are read in
:mod:`drivers.nmea.fields` (times and positions exactly, as text) by the handlers of
:mod:`drivers.nmea.handlers`, :mod:`drivers.nmea.sky` and :mod:`drivers.nmea.proprietary`.
"""

from __future__ import annotations

from typing import NamedTuple

from drivers.nmea.fields import hhmmss_ns

KNOT_MPS = 1852.0 / 3600.0
# The standard sentence types decoded (from any talker).
TYPES = ("GGA", "RMC", "GLL", "GNS", "GSA", "GSV", "VTG", "GST", "GBS", "ZDA")


def xor_checksum(body: bytes | str) -> int:
    """XOR of the bytes between ``$`` and ``*``."""
    if isinstance(body, str):
        body = body.encode("ascii")
    c = 0
    for b in body:
        c ^= b
    return c


def build(body: str) -> bytes:
    """A complete sentence ``$body*HH\\r\\n``."""
    return f"${body}*{xor_checksum(body):02X}\r\n".encode("ascii")


class Sentence(NamedTuple):
    """One checked sentence: talker ("GP"; "P" for proprietary ones), type ("GGA";
    "GRMZ" for ``$PGRMZ``), fields after the address."""

    talker: str
    type: str
    fields: tuple[str, ...]


# ------------------------------------------------------------- field helpers


def time_of_day_ms(s: str) -> int | None:
    """``hhmmss[.sss]`` -> milliseconds since midnight (exact, no float)."""
    ns = hhmmss_ns(s)
    return None if ns is None else ns // 1_000_000


# ------------------------------------------------------------- writers (fake)


def fmt_lat(lat: float, decimals: int = 4) -> tuple[str, str]:
    hemi = "N" if lat >= 0 else "S"
    a = abs(lat)
    d = int(a)
    m = round((a - d) * 60.0, decimals)
    if m >= 60.0:
        d, m = d + 1, 0.0
    return f"{d:02d}{m:0{3 + decimals}.{decimals}f}", hemi


def fmt_lon(lon: float, decimals: int = 4) -> tuple[str, str]:
    hemi = "E" if lon >= 0 else "W"
    a = abs(lon)
    d = int(a)
    m = round((a - d) * 60.0, decimals)
    if m >= 60.0:
        d, m = d + 1, 0.0
    return f"{d:03d}{m:0{3 + decimals}.{decimals}f}", hemi


def fmt_time(ms: int) -> str:
    s, ms = divmod(ms, 1000)
    h, s = divmod(s, 3600)
    m, s = divmod(s, 60)
    return f"{h:02d}{m:02d}{s:02d}.{ms // 10:02d}"
