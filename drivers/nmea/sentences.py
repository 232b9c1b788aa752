"""NMEA 0183 sentences: framing check, XOR checksum, and the fields of GGA, RMC, GSA, VTG,
GST and ZDA from any talker (GP, GN, GL, GA, GB, BD, ...).

A sentence is ``$<talker><type>,f1,f2,...*HH`` where HH is the XOR of the bytes between
``$`` and ``*``. Parsing is by plain string splitting (no regular expressions); numbers that
matter to the millisecond or nanodegree (time of day, latitude, longitude) are split into
their integer and fractional parts as text, so that ``132827.20`` is 27.200 s and not
27.1999... ("fuzzy arithmetic", see gpsd's nmea-fuzzy-cases log).
"""

from __future__ import annotations

from dataclasses import dataclass

KNOT_MPS = 1852.0 / 3600.0
TYPES = ("GGA", "RMC", "GSA", "VTG", "GST", "ZDA")


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


@dataclass(frozen=True, slots=True)
class Sentence:
    """One checked sentence: talker ("GP"), type ("GGA"), fields after the address."""

    talker: str
    type: str
    fields: tuple[str, ...]


# ------------------------------------------------------------- field helpers


def time_of_day_ms(s: str) -> int | None:
    """``hhmmss[.sss]`` -> milliseconds since midnight (exact, no float)."""
    if len(s) < 6:
        return None
    hh, mm, rest = s[0:2], s[2:4], s[4:]
    whole, _, frac = rest.partition(".")
    if not (hh.isdigit() and mm.isdigit() and whole.isdigit() and (not frac or frac.isdigit())):
        return None
    ms = int((frac + "000")[:3]) if frac else 0
    h, m, sec = int(hh), int(mm), int(whole)
    if h > 23 or m > 59 or sec > 60:
        return None
    return ((h * 60 + m) * 60 + sec) * 1000 + ms


def latlon(value: str, hemi: str, deg_digits: int) -> float | None:
    """``DDMM.mmmm`` (lat, 2 degree digits) or ``DDDMM.mmmm`` (lon, 3) -> signed degrees."""
    if not value or not hemi:
        return None
    whole, _, frac = value.partition(".")
    if len(whole) < deg_digits + 2 or not whole.isdigit() or (frac and not frac.isdigit()):
        return None
    deg = int(whole[:-2])
    minutes = int(whole[-2:]) + (int(frac) / 10 ** len(frac) if frac else 0.0)
    if minutes >= 60.0:
        return None
    out = deg + minutes / 60.0
    if hemi in ("S", "W"):
        out = -out
    elif hemi not in ("N", "E"):
        return None
    limit = 90.0 if deg_digits == 2 else 180.0
    return out if abs(out) <= limit else None


def num(s: str) -> float | None:
    if not s:
        return None
    try:
        v = float(s)
    except ValueError:
        return None
    return v if v == v and abs(v) != float("inf") else None


def integer(s: str) -> int | None:
    return int(s) if s.isdigit() else None


def date_ddmmyy(s: str) -> tuple[int, int, int] | None:
    """RMC ``ddmmyy`` -> (year, month, day); two-digit years 80-99 are 19xx."""
    if len(s) != 6 or not s.isdigit():
        return None
    d, m, y = int(s[0:2]), int(s[2:4]), int(s[4:6])
    if not (1 <= d <= 31 and 1 <= m <= 12):
        return None
    return (1900 + y if y >= 80 else 2000 + y, m, d)


# ------------------------------------------------------------- sentence records


@dataclass(frozen=True, slots=True)
class GGA:
    time_ms: int | None
    lat: float | None
    lon: float | None
    quality: int
    satellites: int | None
    hdop: float | None
    alt_msl: float | None
    geoid_sep: float | None


@dataclass(frozen=True, slots=True)
class RMC:
    time_ms: int | None
    valid: bool
    lat: float | None
    lon: float | None
    speed_mps: float | None
    course_deg: float | None
    date: tuple[int, int, int] | None
    faa: str


@dataclass(frozen=True, slots=True)
class GSA:
    mode: int | None  # 1 no fix, 2 2D, 3 3D
    pdop: float | None
    hdop: float | None
    vdop: float | None
    used: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class VTG:
    course_deg: float | None
    speed_mps: float | None
    faa: str


@dataclass(frozen=True, slots=True)
class GST:
    time_ms: int | None
    rms: float | None
    std_lat: float | None
    std_lon: float | None
    std_alt: float | None


@dataclass(frozen=True, slots=True)
class ZDA:
    time_ms: int | None
    date: tuple[int, int, int] | None


Record = GGA | RMC | GSA | VTG | GST | ZDA


def _f(fields: tuple[str, ...], i: int) -> str:
    return fields[i] if i < len(fields) else ""


def parse_gga(f: tuple[str, ...]) -> GGA | None:
    if len(f) < 9:
        return None
    q = integer(_f(f, 5))
    return GGA(
        time_of_day_ms(_f(f, 0)),
        latlon(_f(f, 1), _f(f, 2), 2),
        latlon(_f(f, 3), _f(f, 4), 3),
        q if q is not None else 0,
        integer(_f(f, 6)),
        num(_f(f, 7)),
        num(_f(f, 8)),
        num(_f(f, 10)),
    )


def parse_rmc(f: tuple[str, ...]) -> RMC | None:
    if len(f) < 9:
        return None
    knots = num(_f(f, 6))
    return RMC(
        time_of_day_ms(_f(f, 0)),
        _f(f, 1) == "A",
        latlon(_f(f, 2), _f(f, 3), 2),
        latlon(_f(f, 4), _f(f, 5), 3),
        None if knots is None else knots * KNOT_MPS,
        num(_f(f, 7)),
        date_ddmmyy(_f(f, 8)),
        _f(f, 11)[:1],
    )


def parse_gsa(f: tuple[str, ...]) -> GSA | None:
    if len(f) < 17:
        return None
    mode = integer(f[1])
    used = tuple(int(x) for x in f[2:14] if x.isdigit())
    return GSA(mode if mode in (1, 2, 3) else None, num(f[14]), num(f[15]), num(f[16]), used)


def parse_vtg(f: tuple[str, ...]) -> VTG | None:
    if len(f) < 7:
        return None
    # NMEA 2.3+: course,T,course,M,knots,N,kmh,K[,faa]; old form without unit letters.
    if _f(f, 1) == "T":
        knots, kmh, faa = num(_f(f, 4)), num(_f(f, 6)), _f(f, 8)[:1]
    else:
        knots, kmh, faa = num(_f(f, 2)), num(_f(f, 3)), ""
    speed = knots * KNOT_MPS if knots is not None else (kmh / 3.6 if kmh is not None else None)
    return VTG(num(f[0]), speed, faa)


def parse_gst(f: tuple[str, ...]) -> GST | None:
    if len(f) < 8:
        return None
    return GST(time_of_day_ms(f[0]), num(f[1]), num(f[5]), num(f[6]), num(f[7]))


def parse_zda(f: tuple[str, ...]) -> ZDA | None:
    """ZDA ``time,dd,mm,yyyy,...``: empty date fields give no date; a date that is there but
    out of range (a year other than four digits in 1900-2200, as gpsd checks) is malformed."""
    if len(f) < 4:
        return None
    if not (f[1] or f[2] or f[3]):
        return ZDA(time_of_day_ms(f[0]), None)
    d, m, y = integer(f[1]), integer(f[2]), integer(f[3])
    if d is None or m is None or y is None or len(f[3]) != 4:
        return None
    if not (1900 <= y <= 2200 and 1 <= m <= 12 and 1 <= d <= 31):
        return None
    return ZDA(time_of_day_ms(f[0]), (y, m, d))


PARSERS = {
    "GGA": parse_gga,
    "RMC": parse_rmc,
    "GSA": parse_gsa,
    "VTG": parse_vtg,
    "GST": parse_gst,
    "ZDA": parse_zda,
}


def parse_record(s: Sentence) -> Record | None:
    """Typed record of a supported sentence, None for others or malformed fields."""
    p = PARSERS.get(s.type)
    return p(s.fields) if p else None


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
