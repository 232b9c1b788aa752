"""gpsd's error model and derived quantities, run after every sentence merged into a fix.

As gpsd's ``gpsd_error_model``: altitudes above the ellipsoid and mean sea level from each
other and the geoid separation; climb from the vertical velocity or from the altitudes of
this and the previous epoch's fix; speed and track from the north/east velocity, or the
speed from the distance to the previous fix; magnetic track from the variation; and the
95 % error estimates from the DOPs times gpsd's user equivalent range errors (UERE: 15 m
horizontal per axis, 23 m vertical, 19 m position; a quarter of that with DGPS):
``epx/epy = x/ydop * 15``, ``epv = vdop * 23``, ``eph = hdop * 19``, ``sep = pdop * 19``,
and from two epochs ``eps`` (speed), ``epc`` (climb) and ``epd`` (track). Like gpsd, the
estimates a fix already holds are kept for the rest of its epoch (``eph``, ``epv``,
``sep``: computed from the DOPs known when the fix first had a mode to carry them).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from drivers.nmea.fixstate import DEFERRED, MODE_2D, MODE_3D, STATUS_DGPS

if TYPE_CHECKING:
    from drivers.nmea.session import Session

WGS84_A = 6378137.0
WGS84_B = 6356752.314245
WGS84_F = 1.0 / 298.257223563
# (horizontal per axis, vertical, position) user equivalent range errors, metres at 95 %
UERE = (15.0, 23.0, 19.0)
UERE_DGPS = (3.75, 5.75, 4.75)
_MAX_RATE = 9999.9


def earth_distance(lat1, lon1, lat2, lon2) -> float | None:
    """Vincenty's inverse formula on WGS84 (metres); None if a point is unknown or the
    iteration does not converge (gpsd's earth_distance)."""
    if lat1 is None or lon1 is None or lat2 is None or lon2 is None:
        return None
    f = WGS84_F
    big_l = math.radians(lon2 - lon1)
    u1 = math.atan((1 - f) * math.tan(math.radians(lat1)))
    u2 = math.atan((1 - f) * math.tan(math.radians(lat2)))
    su1, cu1, su2, cu2 = math.sin(u1), math.cos(u1), math.sin(u2), math.cos(u2)
    lam = big_l
    for _ in range(100):
        sl, cl = math.sin(lam), math.cos(lam)
        ss = math.hypot(cu2 * sl, cu1 * su2 - su1 * cu2 * cl)
        if ss == 0:
            return 0.0
        cs = su1 * su2 + cu1 * cu2 * cl
        sigma = math.atan2(ss, cs)
        sa = cu1 * cu2 * sl / ss
        c2a = 1 - sa * sa
        c2m = cs - 2 * su1 * su2 / c2a if c2a != 0 else 0.0
        c = f / 16 * c2a * (4 + f * (4 - 3 * c2a))
        prev = lam
        lam = big_l + (1 - c) * f * sa * (sigma + c * ss * (c2m + c * cs * (2 * c2m * c2m - 1)))
        if abs(lam - prev) <= 1e-12:
            break
    else:
        return None
    u_sq = c2a * (WGS84_A**2 - WGS84_B**2) / WGS84_B**2
    a = 1 + u_sq / 16384 * (4096 + u_sq * (-768 + u_sq * (320 - 175 * u_sq)))
    b = u_sq / 1024 * (256 + u_sq * (-128 + u_sq * (74 - 47 * u_sq)))
    ds = b * ss * (c2m + b / 4 * (cs * (-1 + 2 * c2m * c2m)
                                  - b / 6 * c2m * (-3 + 4 * ss * ss) * (-3 + 4 * c2m * c2m)))  # fmt: skip
    return WGS84_B * a * (sigma - ds)


# the largest radii of curvature of WGS84 (metres): the meridian's, a / sqrt(1 - e^2), at
# the poles, and the parallel's, N cos(lat) <= a, at the equator
_M_MAX = 6399593.7
_PARALLEL_MAX = WGS84_A


def _nearer_than(lat1, lon1, lat2, lon2, d: float) -> bool:
    """Whether two points are surely nearer than ``d`` metres, so that the distance
    need not be computed to know it is not over ``d``: the geodesic is no longer than
    the path along the meridian, then along the parallel, and that path no longer than
    its angles times the largest radii (with a margin far above Vincenty's error)."""
    if lat1 is None or lon1 is None or lat2 is None or lon2 is None:
        return False
    dlon = abs(lon2 - lon1) % 360.0
    if dlon > 180.0:
        dlon = 360.0 - dlon
    return (_M_DEG * abs(lat2 - lat1) + _PARALLEL_DEG * dlon) * 1.001 + 0.01 < d


_M_DEG = _M_MAX * math.pi / 180.0  # (metres in a degree, at most)
_PARALLEL_DEG = _PARALLEL_MAX * math.pi / 180.0


def deferred_speed(lat1, lon1, lat2, lon2, dt: float) -> float | None:
    """Speed from the distance between two fixes (gpsd's, when no sentence gave one)."""
    d = earth_distance(lat1, lon1, lat2, lon2)
    return None if d is None else _sane(d / dt)


def _sane(v: float | None) -> float | None:
    return None if v is None or abs(v) > _MAX_RATE else v


def _norm360(deg: float) -> float:
    if deg < 0.0:
        return deg + 360.0
    if deg >= 360.0:
        return deg - 360.0
    return deg


def _velocities(fix) -> None:
    """Sane north/east/down velocities; climb, speed and track from them when missing."""
    fix.vel_n, fix.vel_e, fix.vel_d = _sane(fix.vel_n), _sane(fix.vel_e), _sane(fix.vel_d)
    if fix.vel_d is not None and fix.climb is None:
        fix.climb = -fix.vel_d
    if fix.vel_n is not None and fix.vel_e is not None:
        if fix.speed is None:
            fix.speed = math.hypot(fix.vel_n, fix.vel_e)
        if fix.track is None:
            fix.track = math.degrees(math.atan2(fix.vel_e, fix.vel_n))


def _tracks(st: Session, fix) -> None:
    """The true track from the magnetic one and the variation, or the magnetic from the
    true; each moved into 0-360 degrees by 360 once, as gpsd does (``st._unnormed``: one
    is still outside, so another run would move it again)."""
    track, magvar, magtrack = fix.track, fix.magvar, fix.magtrack
    if (
        magvar is None
        and (track is None or 0.0 <= track < 360.0)
        and (magtrack is None or 0.0 <= magtrack < 360.0)
    ):  # (the usual fix: nothing to derive or move)
        st._unnormed = False
        return
    if magvar is not None:
        if magtrack is None and track is not None:
            fix.magtrack = magtrack = track + magvar
        elif magtrack is not None and track is None:
            track = magtrack - magvar
    unnormed = False
    if track is not None and not 0.0 <= track < 360.0:
        track = _norm360(track)
        unnormed = not 0.0 <= track < 360.0
    fix.track = track
    if magtrack is not None and not 0.0 <= magtrack < 360.0:
        fix.magtrack = magtrack = _norm360(magtrack)
        unnormed = unnormed or not 0.0 <= magtrack < 360.0
    st._unnormed = unnormed


def motion_model(st: Session) -> None:
    """:func:`error_model` after a sentence that changed only the speed, the true or the
    magnetic track or the variation of a fix, when the model ran on that fix after its
    other fields last changed, the DOPs are those it saw, no track was left outside
    0-360 degrees, the fix has no velocities and its speed is known (the caller's
    conditions): the rest of the model then comes out as it was (the same fix, times,
    previous fix and DOPs), so what it does is check the speed and the tracks. An
    insane speed (which the model makes unknown, then deferred) takes the whole model."""
    fix = st.fix
    speed = fix.speed
    if speed is not None and abs(speed) > _MAX_RATE:  # (False for a deferred speed)
        error_model(st, {})
        return
    _tracks(st, fix)


def _start(st: Session) -> tuple[Any, Any, int | None, Any, float]:
    """What both error models start with: the DOPs (kept as this run's), the fix, its
    time, the previous fix and the time since it (-1 without a time)."""
    dop = st.sky.dop
    st._dops = dop.copy()
    fix = st.fix
    t = fix.time_ns
    old = st.oldfix
    if t:
        last = st.lastfix
        dt = (t - (last.time_ns or 0)) * 1e-9
        if dt > 0.0099 or dt < -0.0099:
            st.oldfix = old = last  # time moved on: the last fix is now the previous one
        else:
            dt = (t - (old.time_ns or 0)) * 1e-9
    else:
        dt = -1.0
    return dop, fix, t, old, dt


def error_model(st: Session, new: dict) -> None:
    """Update ``st.fix`` after a merge (``new``: what the sentence itself gave). The
    session keeps the DOPs this run saw (``st._dops``) and whether it left a track outside
    0-360 degrees (``st._unnormed``: gpsd moves such a track by 360 each run), so that a
    sentence changing neither the fix nor the DOPs need not run it again."""
    dop, fix, t, old, dt = _start(st)
    lat, lon = fix.lat, fix.lon
    if lat is None or lon is None or not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        fix.lat = fix.lon = lat = lon = None
    # what follows from the fix's own fields: velocities, track, altitudes
    speed = fix.speed
    if speed is not None and abs(speed) > _MAX_RATE:  # (False for a deferred speed)
        fix.speed = speed = None
    v = fix.climb
    if v is not None and abs(v) > _MAX_RATE:
        fix.climb = None
    if fix.vel_n is not None or fix.vel_e is not None or fix.vel_d is not None:
        _velocities(fix)
        speed = fix.speed
    track, magtrack = fix.track, fix.magtrack
    if (
        fix.magvar is None
        and (track is None or 0.0 <= track < 360.0)
        and (magtrack is None or 0.0 <= magtrack < 360.0)
    ):  # (_tracks of the usual fix: nothing to derive or move)
        st._unnormed = False
    else:
        _tracks(st, fix)
    sep = fix.geoid_sep
    if sep is not None:
        alt = fix.alt_msl
        if alt is None:
            alt = fix.alt_hae
            if alt is not None:
                fix.alt_msl = alt - sep
        elif fix.alt_hae is None:
            fix.alt_hae = alt + sep
    # what follows from the previous epoch's fix: speed, climb
    mode = fix.mode
    moved = dt > 0 and mode >= MODE_2D and old.mode >= MODE_2D
    if moved:
        if speed is None:
            fix.speed = DEFERRED
            fix.speed_args = (lat, lon, old.lat, old.lon, dt)
        if (mode >= MODE_3D and old.mode >= MODE_3D and fix.climb is None
                and fix.alt_hae is not None and old.alt_hae is not None):  # fmt: skip
            climb = (fix.alt_hae - old.alt_hae) / dt
            fix.climb = None if abs(climb) > _MAX_RATE else climb  # (_sane)
    if t and fix.ept is None:
        fix.ept = 0.005
    if mode < MODE_2D:
        if t:
            st.lastfix = fix
        return
    # the 95 % estimates: from the DOPs (kept once the fix has them), then from the
    # previous epoch's fix (speed, track and climb errors)
    if dop:
        h_uere, v_uere, p_uere = UERE_DGPS if fix.status == STATUS_DGPS else UERE
        get = dop.get
        if "epx" not in new and (xdop := get("xdop")) is not None:
            fix.epx = xdop * h_uere
        if "epy" not in new and (ydop := get("ydop")) is not None:
            fix.epy = ydop * h_uere
        if fix.epv is None and mode >= MODE_3D and (vdop := get("vdop")) is not None:
            fix.epv = vdop * v_uere
        if fix.eph is None and (hdop := get("hdop")) is not None:
            fix.eph = hdop * p_uere
        if fix.sep is None and (pdop := get("pdop")) is not None:
            fix.sep = pdop * p_uere
    if moved:
        epx, epy = fix.epx, fix.epy
        # (C's x > y ? x : y, a NaN (None) comparing false)
        opp = epx if epx is not None and epy is not None and epx > epy else epy
        a, b = old.epx, old.epy
        if a is not None and b is not None and "eps" not in new:
            a = a if a > b else b
            fix.eps = None if opp is None else (a + opp) / dt
        if (
            fix.epd is None
            and opp is not None
            and not _nearer_than(old.lat, old.lon, lat, lon, opp)
        ):
            adj = st.distance(old.lat, old.lon, lat, lon)
            if adj is not None and adj > opp:
                fix.epd = math.degrees(2 * math.asin(opp / math.hypot(adj, opp)))
        epv = fix.epv
        if epv is not None and old.epv is not None and "epc" not in new:
            fix.epc = (old.epv + epv) / dt
    if t:
        st.lastfix = fix  # the fix itself: a later sentence without a time copies it first
