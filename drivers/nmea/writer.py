"""Write one epoch of NMEA sentences (GGA, GSA, RMC, VTG, GST, ZDA) for a fix.

Used by the fake receiver and by the codec's round-trip tests: the same checksum and field
formats both ways. Positions are written with ``decimals`` decimals of minutes (default 5,
about 2 cm), times to the centisecond.
"""

from __future__ import annotations

import datetime as dt

from drivers.nmea.sentences import KNOT_MPS, build, fmt_lat, fmt_lon, fmt_time
from msgs import GpsFix

DEFAULT_TYPES = ("GGA", "GSA", "RMC", "VTG", "GST", "ZDA")


def epoch_sentences(
    fix: GpsFix,
    when: dt.datetime,
    talker: str = "GP",
    types: tuple[str, ...] = DEFAULT_TYPES,
    decimals: int = 5,
) -> bytes:
    """The sentences of one epoch. ``fix.mode`` < 2 writes an epoch without a fix."""
    when = when.astimezone(dt.UTC)
    ms = (when.hour * 3600 + when.minute * 60 + when.second) * 1000 + when.microsecond // 1000
    t = fmt_time(ms)
    has_fix = fix.mode >= 2 and fix.lat_deg is not None and fix.lon_deg is not None
    if has_fix:
        la, lah = fmt_lat(fix.lat_deg, decimals)  # type: ignore[arg-type]
        lo, loh = fmt_lon(fix.lon_deg, decimals)  # type: ignore[arg-type]
    else:
        la = lah = lo = loh = ""
    out = []
    for kind in types:
        if kind == "GGA":
            q = (fix.quality or 1) if has_fix else 0
            alt = f"{fix.alt_msl_m:.2f}" if has_fix and fix.alt_msl_m is not None else ""
            sep = f"{fix.geoid_sep_m:.1f}" if has_fix and fix.geoid_sep_m is not None else ""
            sats = f"{fix.satellites or 0:02d}"
            hdop = f"{fix.hdop:.1f}" if fix.hdop is not None else ""
            body = f"GGA,{t},{la},{lah},{lo},{loh},{q},{sats},{hdop},{alt},M,{sep},M,,"
        elif kind == "GSA":
            mode = fix.mode if fix.mode in (1, 2, 3) else 1
            n = fix.satellites or 0 if has_fix else 0
            prns = [f"{p:02d}" for p in range(1, min(n, 12) + 1)] + [""] * (12 - min(n, 12))
            dops = [f"{x:.1f}" if x is not None else "" for x in (fix.pdop, fix.hdop, fix.vdop)]
            body = f"GSA,A,{mode}," + ",".join(prns) + "," + ",".join(dops)
        elif kind == "RMC":
            status = "A" if has_fix else "V"
            kn = f"{(fix.speed_mps or 0.0) / KNOT_MPS:.3f}" if has_fix else ""
            cog = f"{fix.course_deg:.2f}" if has_fix and fix.course_deg is not None else ""
            date = when.strftime("%d%m%y")
            faa = "A" if has_fix else "N"
            body = f"RMC,{t},{status},{la},{lah},{lo},{loh},{kn},{cog},{date},,,{faa}"
        elif kind == "VTG":
            if has_fix:
                cog = f"{fix.course_deg:.2f}" if fix.course_deg is not None else ""
                v = fix.speed_mps or 0.0
                body = f"VTG,{cog},T,,M,{v / KNOT_MPS:.3f},N,{v * 3.6:.3f},K,A"
            else:
                body = "VTG,,T,,M,,N,,K,N"
        elif kind == "GST":

            def s(x: float | None) -> str:
                return f"{x:.2f}" if has_fix and x is not None else ""

            body = (
                f"GST,{t},{s(fix.std_lat_m)},,,,{s(fix.std_lat_m)},"
                f"{s(fix.std_lon_m)},{s(fix.std_alt_m)}"
            )
        elif kind == "ZDA":
            body = f"ZDA,{t},{when.day:02d},{when.month:02d},{when.year:04d},00,00"
        else:
            raise ValueError(f"cannot write NMEA sentence type {kind!r}")
        out.append(build(talker + body))
    return b"".join(out)
