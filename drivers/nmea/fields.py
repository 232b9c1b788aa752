"""NMEA field values read as gpsd reads them: numbers, integers, times, dates, positions.

- :func:`fnum` is gpsd's ``safe_atof``: the longest number at the start of the field
  (``12a`` is 12), None where gpsd has NaN (empty, no digits, not finite);
- :func:`atoi` is C's ``atoi``: the leading integer, 0 when there is none;
- :func:`hhmmss_ns` is a time of day (``hhmmss[.sss]``) in ns, exact (the fraction is read
  as text, so ``132827.20`` is 27.200 s, not 27.1999...: gpsd's nmea-fuzzy-cases log);
- :func:`ddmmyy` is an RMC date, the century from the two-digit year (80-99 is 19xx);
- :func:`latlon` is ``DDMM.mmm`` + hemisphere, computed as gpsd does (whole minutes as
  an integer, the fraction added once, times 1/60), so results agree to the last bit.

Fields that repeat within an epoch (the time, the position in GGA and RMC) are parsed
once: the time and position parsers keep small caches of recent fields, and
:func:`number` is :func:`fnum` with one.
"""

from __future__ import annotations

import math
import re

from drivers.nmea.memo import table

_NUMBER = re.compile(r"\s*([-+]?)(\d*)(?:\.(\d*))?(?:[eE]([-+]?\d+))?")
_INT = re.compile(r"\s*([-+]?\d+)")
_START = frozenset("0123456789-+.")
_CACHE_MAX = 64


def fnum(s: str) -> float | None:
    """gpsd's safe_atof; None for NaN (empty, nothing numeric) and for infinities."""
    if not s:
        return None
    try:
        v = float(s)  # Python reads what safe_atof reads, and more: checked below
    except ValueError:
        v = _prefix_float(s)
    else:
        if "_" in s or s[0] not in _START:  # 1_0, " 5", "nan", "inf": read as gpsd does
            v = _prefix_float(s)
    if v is None or v - v != 0.0:  # NaN or infinite
        return None
    return v


NUMBERS: dict[str, float | None] = table({})  # field -> fnum(field), for number()


def number(s: str) -> float | None:
    """:func:`fnum`, remembered for the last fields read: a receiver repeats many (the
    geoid separation, the DOPs, an altitude or course that holds, a VTG's course and speed
    after the RMC's). Hot paths look in ``NUMBERS`` first: ``NUMBERS.get(s) or
    read_number(s)`` (a false value, None or 0.0, is read again, to the same value)."""
    v = NUMBERS.get(s, _MISSING)
    if v is _MISSING:
        if len(NUMBERS) >= _NUMBERS_MAX:
            NUMBERS.clear()
        v = NUMBERS[s] = fnum(s)
    return v  # type: ignore[return-value]


def read_number(s: str) -> float | None:
    """:func:`number` once ``NUMBERS`` had no true value for the field (hot paths:
    ``NUMBERS.get(s) or read_number(s)``): fnum(s), kept in the table."""
    if len(NUMBERS) >= _NUMBERS_MAX:
        NUMBERS.clear()
    try:  # (fnum of the usual field, written out)
        v = float(s)
    except ValueError:
        v = NUMBERS[s] = fnum(s)
        return v
    if "_" in s or s[0] not in _START or v - v != 0.0:
        v = fnum(s)
    NUMBERS[s] = v
    return v


_MISSING = object()
_NUMBERS_MAX = 256


def _prefix_float(s: str) -> float | None:
    m = _NUMBER.match(s)
    if m is None:
        return None
    sign, whole, frac, exp = m.groups()
    stripped = s.lstrip()
    if not stripped or stripped[0] not in _START:
        return None
    if not whole and not frac:
        return -0.0 if sign == "-" else 0.0
    text = f"{sign}{whole or '0'}.{frac or '0'}"
    if exp is not None and len(exp.lstrip("+-")) <= 4:
        text += f"e{exp}"
    elif exp is not None:
        return math.inf if not exp.startswith("-") else 0.0
    try:
        return float(text)
    except (ValueError, OverflowError):
        return None


def atoi(s: str) -> int:
    """C's atoi: the leading (signed) integer of the field, 0 when there is none."""
    if s.isdigit() and s.isascii():
        return int(s)
    m = _INT.match(s)
    return int(m.group(1)) if m else 0


_HHMMSS: dict[str, int | None] = table({})


def hhmmss_ns(s: str) -> int | None:
    """``hhmmss[.fff]`` -> ns since midnight; None if malformed or out of range."""
    v = _HHMMSS.get(s, -1)
    if v != -1:
        return v
    v = _parse_hhmmss(s)
    if len(_HHMMSS) >= _CACHE_MAX:
        _HHMMSS.clear()
    _HHMMSS[s] = v
    return v


def _parse_hhmmss(s: str) -> int | None:
    """:func:`hhmmss_ns` without its table: the hours and minutes, the seconds and what
    follows each looked up (an ordinary field is three look-ups), else
    :func:`_hhmmss_read`."""
    hhmm = _HHMM.get(s[:4])
    if hhmm is not None:
        sec = _SS.get(s[4:6])
        if sec is not None:
            tail = s[6:]
            return hhmm[0] + sec[0] + (_TAIL.get(tail) or _tail(tail))[0]
    return _hhmmss_read(s)


def clock(s: str) -> tuple[int | None, float | None]:
    """``(hhmmss_ns(s), fnum(s))``: a time field as a time of day and as a number (what
    gpsd compares to tell a new cycle), from the same look-ups. The number of an ordinary
    field, ``hhmmss.fff``, is its digits over a power of ten: an exact integer division,
    correctly rounded as float() rounds the text."""
    hhmm = _HHMM.get(s[:4])
    if hhmm is not None:
        sec = _SS.get(s[4:6])
        if sec is not None:
            tail = s[6:]
            ns, scale, digits = _TAIL.get(tail) or _tail(tail)
            if scale:
                return hhmm[0] + sec[0] + ns, ((hhmm[1] + sec[1]) * scale + digits) / scale
            return hhmm[0] + sec[0] + ns, fnum(s)
    return _hhmmss_read(s), fnum(s)


def _hhmmss_read(s: str) -> int | None:
    head = s[:6]
    if len(head) < 6 or not (head.isdigit() and head.isascii()):
        return None
    h, rest = divmod(int(head), 10000)
    m, sec = divmod(rest, 100)
    if h > 23 or m > 59 or sec > 60:
        return None
    return ((h * 60 + m) * 60 + sec) * 1_000_000_000 + _tail(s[6:])[0]


def _tail(tail: str) -> tuple[int, int, int]:
    """What follows ``hhmmss``: (its ns: those of a fraction ``.fff``, 0 for anything
    else; and for a plain fraction, or nothing, 10 ** its digits and their value, else
    0, 0)."""
    ns = 0
    if tail[:1] == "." and tail[1:2].isdigit():
        digits = tail[1:]
        if len(digits) <= 9:
            if digits.isdigit() and digits.isascii():
                ns = int(digits) * _POW10[9 - len(digits)]
            else:
                lead = _INT.match(digits)
                ns = int(lead.group(1)) * _POW10[9 - len(digits)] if lead else 0
    digits = tail[1:]
    if tail in ("", "."):
        read = (ns, 1, 0)
    elif tail[0] == "." and digits.isdigit() and digits.isascii() and len(digits) < 20:
        read = (ns, _POW10[len(digits)], int(digits))
    else:
        read = (ns, 0, 0)
    if len(_TAIL) >= _CACHE_MAX:
        _TAIL.clear()
    _TAIL[tail] = read
    return read


# "hhmm" of every valid hour and minute -> (ns since midnight, hhmm00 as a number);
# "ss" (00-60) -> (ns, ss); what follows hhmmss -> _tail(...)
_HHMM = {f"{h:02d}{m:02d}": ((h * 60 + m) * 60_000_000_000, (h * 100 + m) * 100)
         for h in range(24) for m in range(60)}  # fmt: skip
_SS = {f"{sec:02d}": (sec * 1_000_000_000, sec) for sec in range(61)}
_TAIL: dict[str, tuple[int, int, int]] = table({})
_POW10 = tuple(10**k for k in range(130))


def ddmmyy(s: str) -> tuple[int, int, int] | None:
    """RMC ``ddmmyy`` -> (year, month, day); two-digit years 80-99 are 19xx."""
    if len(s) != 6 or not (s.isdigit() and s.isascii()):
        return None
    d, m, y = int(s[0:2]), int(s[2:4]), int(s[4:6])
    if not (1 <= d <= 31 and 1 <= m <= 12):
        return None
    return (1900 + y if y >= 80 else 2000 + y, m, d)


def _degrees(field: str) -> float | None:
    """gpsd's decode_lat_or_lon: ``DDDMM.mmm`` -> degrees (no sign), None if malformed.
    The whole minutes of the usual field are looked up (they hold from fix to fix): its
    degrees times 60 plus minutes, to which the fraction is added once (gpsd's sum)."""
    dot = field.find(".")
    if dot > 0:
        minutes = _MINUTES.get(field[:dot])
        if minutes is not None:
            frac = field[dot + 1 :]
            if frac.isdigit() and frac.isascii() and len(frac) < 100:
                # (float(".fff"): the exact quotient, correctly rounded as float() rounds)
                return (minutes + int(frac) / _POW10[len(frac)]) * (1.0 / 60.0)
    return _degrees_read(field)


def _degrees_read(field: str) -> float | None:
    whole, dot, frac = field.partition(".")
    if not dot:
        return None
    if whole.isdigit() and frac.isdigit() and field.isascii():  # the usual field
        minutes = int(whole)
        minutes -= minutes // 100 * 40
        if len(_MINUTES) >= _CACHE_MAX:
            _MINUTES.clear()
        _MINUTES[whole] = minutes
        return (minutes + float(field[len(whole) :])) * (1.0 / 60.0)
    m = _INT.match(whole)
    if m is None or m.end() != len(whole):
        if whole:
            return None
        minutes = 0
    else:
        minutes = int(m.group(1))
    degrees = int(minutes / 100)
    minutes -= degrees * 40
    f = fnum("." + frac) if frac else 0.0
    if f is None:
        return None
    return (minutes + f) * (1.0 / 60.0)


_MINUTES: dict[str, int] = table({})  # a position field's whole minutes (digits) -> deg * 60 + min


_LATLON: dict[tuple[str, str, str, str], tuple[float, float] | None] = table({})
_NOT_READ = object()


def latlon(lat: str, ns: str, lon: str, ew: str) -> tuple[float, float] | None:
    """(lat, lon) in signed degrees from the four NMEA fields; None if any is missing or
    malformed (gpsd's do_lat_lon; S and W are negative, any other letter positive)."""
    key = (lat, ns, lon, ew)
    v = _LATLON.get(key, _NOT_READ)
    if v is not _NOT_READ:
        return v  # type: ignore[return-value]
    v = None
    if lat and ns and lon and ew:
        a = _usual_degrees(lat)
        b = _usual_degrees(lon)
        if a is not None and b is not None:
            v = (-a if ns[0] == "S" else a, -b if ew[0] == "W" else b)
    if len(_LATLON) >= _CACHE_MAX:
        _LATLON.clear()
    _LATLON[key] = v
    return v


def _usual_degrees(text: str) -> float | None:
    """:func:`_degrees` of a position field: the usual ``dddmm.mmmm`` read by table
    (degrees and minutes, then the fraction as an exact integer over a power of ten),
    anything else through ``_degrees_read``."""
    dot = text.find(".")
    if dot > 0 and (minutes := _MINUTES.get(text[:dot])) is not None:
        frac = text[dot + 1 :]
        if frac.isdigit() and frac.isascii() and len(frac) < 100:
            return (minutes + int(frac) / _POW10[len(frac)]) * (1.0 / 60.0)
    return _degrees_read(text)


def faa_status(mode: str) -> int:
    """gpsd's status of an FAA mode indicator (A autonomous, D differential, ...)."""
    return _FAA.get(mode[:1], 1)


# '' missing, C/U Quectel caution/unsafe, N not valid -> unknown; P precise -> DGPS.
_FAA = {"": 0, "C": 0, "N": 0, "U": 0, "A": 1, "D": 2, "E": 5, "F": 4, "P": 2, "R": 3,
        "M": 8, "S": 8}  # fmt: skip
