"""GpsFix and GpsSky as gpsd's JSON objects (TPV, SKY, GST): gpsd's names, units and
decimals.

gpsd's JSON uses metres, m/s, degrees and seconds, as the messages do; each number is
rounded to the decimals gpsd prints (9 for latitude and longitude, 4 for altitudes and
track, 3 for speeds and most error estimates, 2 for DOPs) and a field is left out when
the message has none, as gpsd leaves out what it does not know. ``status`` is printed
from DGPS up (gpsd does not print "unknown" or plain GPS).
"""

from __future__ import annotations

from typing import Any

from msgs import GpsFix, GpsSky

# gpsd TPV key -> (GpsFix attribute, decimals), in gpsd's order
_TPV: tuple[tuple[str, str, int], ...] = (
    ("ept", "ept_s", 3), ("lat", "lat_deg", 9), ("lon", "lon_deg", 9),
    ("altHAE", "alt_hae_m", 4), ("altMSL", "alt_msl_m", 4), ("epx", "epx_m", 3),
    ("epy", "epy_m", 3), ("epv", "epv_m", 3), ("track", "course_deg", 4),
    ("magtrack", "magtrack_deg", 4), ("magvar", "magvar_deg", 1), ("speed", "speed_mps", 3),
    ("climb", "climb_mps", 3), ("epd", "epd_deg", 4), ("eps", "eps_mps", 2),
    ("epc", "epc_mps", 2), ("velN", "vel_n_mps", 3), ("velE", "vel_e_mps", 3),
    ("velD", "vel_d_mps", 3), ("geoidSep", "geoid_sep_m", 3), ("eph", "eph_m", 3),
    ("sep", "sep_m", 3), ("dgpsAge", "dgps_age_s", 1),
)  # fmt: skip
_DOPS = ("xdop", "ydop", "vdop", "tdop", "hdop", "gdop", "pdop")
_GST = (("rms", "gst_rms_m"), ("major", "gst_major_m"), ("minor", "gst_minor_m"),
        ("orient", "gst_orient_deg"), ("lat", "std_lat_m"), ("lon", "std_lon_m"),
        ("alt", "std_alt_m"))  # fmt: skip


def _r(v: float, decimals: int) -> float:
    v = round(v, decimals)
    return 0.0 if v == 0 else v  # no -0.0


def tpv(fix: GpsFix) -> dict[str, Any]:
    """gpsd's TPV object of a fix."""
    out: dict[str, Any] = {"class": "TPV"}
    if fix.status >= 2:
        out["status"] = fix.status
    out["mode"] = fix.mode
    if fix.time_utc:
        out["time"] = fix.time_utc
    if fix.leap_seconds is not None:
        out["leapseconds"] = fix.leap_seconds
    for key, attr, decimals in _TPV:
        v = getattr(fix, attr)
        if v is not None:
            out[key] = _r(v, decimals)
        if key == "altMSL" and ("altMSL" in out or "altHAE" in out):
            out["alt"] = out.get("altMSL", out.get("altHAE"))  # deprecated, as gpsd
    if fix.dgps_age_s is not None and fix.dgps_station is not None:
        out["dgpsSta"] = fix.dgps_station
    return out


def sky(s: GpsSky) -> dict[str, Any]:
    """gpsd's SKY object of a sky."""
    out: dict[str, Any] = {"class": "SKY"}
    if s.time_utc:
        out["time"] = s.time_utc
    for name in _DOPS:
        v = getattr(s, name)
        if v is not None:
            out[name] = _r(v, 2)
    if s.n_sat is not None:
        out["nSat"] = s.n_sat
    if s.u_sat is not None:
        out["uSat"] = s.u_sat
    if s.n_sat is not None:
        sats = []
        for sat in s.satellites:
            d: dict[str, Any] = {"PRN": sat.prn}
            if sat.elevation_deg is not None:
                d["el"] = _r(sat.elevation_deg, 1)
            if sat.azimuth_deg is not None:
                d["az"] = _r(sat.azimuth_deg, 1)
            if sat.snr_dbhz is not None:
                d["ss"] = _r(sat.snr_dbhz, 1)
            d["used"] = sat.used
            if sat.sv_id:
                d["gnssid"], d["svid"] = sat.gnss_id, sat.sv_id
            sats.append(d)
        out["satellites"] = sats
    return out


def gst(fix: GpsFix) -> dict[str, Any] | None:
    """gpsd's GST object of a fix's pseudorange noise statistics; None without any."""
    values = {k: getattr(fix, a) for k, a in _GST}
    if all(v is None for v in values.values()):
        return None
    out: dict[str, Any] = {"class": "GST"}
    if fix.time_utc:
        out["time"] = fix.time_utc
    out.update({k: _r(v, 3) for k, v in values.items() if v is not None})
    return out


def gpsd_objects(msg: GpsFix | GpsSky) -> list[dict[str, Any]]:
    """The gpsd objects of a message: TPV (and GST when there is one) or SKY."""
    if isinstance(msg, GpsSky):
        return [sky(msg)]
    noise = gst(msg)
    return [tpv(msg)] + ([noise] if noise is not None else [])
