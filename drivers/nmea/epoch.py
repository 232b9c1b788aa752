"""Combine the sentences of one NMEA epoch into one :class:`msgs.GpsFix`, as gpsd would.

An epoch is the set of sentences sharing one UTC time of day (GSA and VTG carry no time
and join the epoch of the sentence before them). An epoch is reported when the next one
starts, or at once when the sentence type that ended the previous epoch arrives (the
"cycle ender", learned as gpsd does), so a live stream reports each fix without waiting a
whole period; if more sentences of the same epoch follow, an updated fix is reported.

Mode follows gpsd (0 unknown, 1 no fix, 2 2D, 3 3D): GGA decides when present (quality
0 -> no fix; a fix with altitude and satellites in use -> 3D, else 2D); otherwise GSA's
mode; otherwise RMC's status (A -> 2D at least, V -> no fix). Position and altitude are
reported only with a fix (mode >= 2). The date comes from the latest RMC or ZDA, so fixes
before the first date have no ``time_utc``. Local metres are about the configured datum,
or the first fix's position when none is configured.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field

from drivers.nmea.local import Datum
from drivers.nmea.sentences import GGA, GSA, GST, RMC, VTG, ZDA, Record
from msgs import GpsFix

# gpsd moves dates before this forward by 1024 weeks when asked (week-counter rollover).
ROLLOVER_S = 1024 * 7 * 86400


@dataclass
class _Epoch:
    time_ms: int | None = None
    stamp_ns: int = 0
    talker: str = ""
    gga: GGA | None = None
    rmc: RMC | None = None
    gsa: GSA | None = None
    vtg: VTG | None = None
    gst: GST | None = None
    types: list[str] = field(default_factory=list)
    dirty: bool = False


class EpochCombiner:
    """Feed typed records in order; get fixes back (see module docstring)."""

    def __init__(self, datum: Datum | None = None, rollover_before_year: int | None = None) -> None:
        self.datum = datum
        self.rollover_before_year = rollover_before_year
        self._date: tuple[int, int, int] | None = None
        self._ep = _Epoch()
        self._ender: str | None = None

    def add(self, talker: str, kind: str, rec: Record, stamp_ns: int) -> list[GpsFix]:
        out: list[GpsFix] = []
        t = getattr(rec, "time_ms", None)
        ep = self._ep
        if t is not None and ep.time_ms is not None and t != ep.time_ms and ep.types:
            if ep.dirty:
                out.append(self._fix(ep))
            self._ender = ep.types[-1]
            ep = self._ep = _Epoch()
        if t is not None:
            ep.time_ms = t
        ep.stamp_ns = stamp_ns
        ep.talker = talker
        ep.types.append(kind)
        ep.dirty = True
        if isinstance(rec, GGA):
            ep.gga = rec
        elif isinstance(rec, RMC):
            ep.rmc = rec
            if rec.date:
                self._date = rec.date
        elif isinstance(rec, GSA):
            ep.gsa = rec
        elif isinstance(rec, VTG):
            ep.vtg = rec
        elif isinstance(rec, GST):
            ep.gst = rec
        elif isinstance(rec, ZDA) and rec.date:
            self._date = rec.date
        if kind == self._ender:
            out.append(self._fix(ep))
        return out

    def flush(self) -> list[GpsFix]:
        """The pending epoch's fix (end of a stream), if it was not reported yet."""
        ep = self._ep
        if ep.types and ep.dirty:
            return [self._fix(ep)]
        return []

    # ------------------------------------------------------------------
    def _mode(self, ep: _Epoch) -> int:
        if ep.gga is not None:
            g = ep.gga
            if g.quality == 0 or g.lat is None or g.lon is None:
                return 1
            if g.alt_msl is not None and g.satellites != 0:
                return 3
            return 2
        if ep.gsa is not None and ep.gsa.mode is not None:
            return ep.gsa.mode
        if ep.rmc is not None:
            return 2 if ep.rmc.valid and ep.rmc.lat is not None else 1
        return 0

    def _time(self, ep: _Epoch) -> str:
        if ep.time_ms is None or self._date is None:
            return ""
        y, m, d = self._date
        try:
            t = dt.datetime(y, m, d, tzinfo=dt.UTC) + dt.timedelta(milliseconds=ep.time_ms)
            if self.rollover_before_year is not None and y < self.rollover_before_year:
                t += dt.timedelta(seconds=ROLLOVER_S)
        except (ValueError, OverflowError):  # 30 February; past year 9999
            return ""
        return f"{t.year:04d}" + t.strftime("-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"

    def _fix(self, ep: _Epoch) -> GpsFix:
        ep.dirty = False
        mode = self._mode(ep)
        g, r, s, v, st = ep.gga, ep.rmc, ep.gsa, ep.vtg, ep.gst
        lat = lon = alt = sep = None
        if mode >= 2:
            if g is not None and g.lat is not None and g.lon is not None:
                lat, lon = g.lat, g.lon
            elif r is not None:
                lat, lon = r.lat, r.lon
            if g is not None:
                alt = g.alt_msl
                sep = g.geoid_sep
        speed = course = None
        if r is not None and r.valid:
            speed, course = r.speed_mps, r.course_deg
        if v is not None and v.faa != "N":
            speed = v.speed_mps if v.speed_mps is not None else speed
            course = v.course_deg if v.course_deg is not None else course
        east = north = None
        if lat is not None and lon is not None:
            if self.datum is None:
                self.datum = Datum(lat, lon)
            east, north = self.datum.to_local(lat, lon)
        return GpsFix(
            stamp_ns=ep.stamp_ns,
            time_utc=self._time(ep),
            lat_deg=lat,
            lon_deg=lon,
            alt_msl_m=alt,
            geoid_sep_m=sep,
            mode=mode,
            quality=g.quality if g is not None else (1 if mode >= 2 else 0),
            satellites=g.satellites if g is not None else (len(s.used) if s else None),
            hdop=(g.hdop if g is not None and g.hdop is not None else (s.hdop if s else None)),
            pdop=s.pdop if s else None,
            vdop=s.vdop if s else None,
            speed_mps=speed,
            course_deg=course,
            std_lat_m=st.std_lat if st else None,
            std_lon_m=st.std_lon if st else None,
            std_alt_m=st.std_alt if st else None,
            east_m=east,
            north_m=north,
            talker=ep.talker,
        )
