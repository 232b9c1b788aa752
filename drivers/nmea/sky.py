"""Satellites: GSA (used) and GSV (in view) as gpsd reads them, and DOPs from the geometry.

PRNs are mapped as gpsd's ``nmeaid_to_prn`` does: NMEA 4.10+ sentences carry a GNSS id,
older ones are told apart by the talker (GL GLONASS, GA Galileo, GB/BD BeiDou, GQ/QZ
QZSS) and by the PRN range. GSA lists of several talkers in one epoch accumulate (GP then
GL, or two GN); a GSV set is complete when its last part arrives, and sets of several
talkers in one epoch (GPGSV then GLGSV) accumulate. A satellite is "used" when a GSA
lists it and its signal to noise is above 0. From a complete set, the DOPs the receiver
did not give are computed from the unit vectors to the satellites used (gpsd's
``fill_dop``: the inverse of the 4x4 normal matrix).
"""

from __future__ import annotations

from drivers.nmea.dops import geometry_dops
from drivers.nmea.fields import atoi, number
from drivers.nmea.fixstate import DOP_SET, MODE_SET, SATELLITE_SET, USED_IS
from drivers.nmea.memo import table
from msgs import GpsSatellite
from msgs.construct import positional_constructor

MAXCHANNELS = 130
# talker letter -> NMEA 4.10 GNSS id (GSA/GSV of one constellation)
_TALKER_GNSS = {"A": 3, "B": 4, "D": 4, "I": 6, "L": 2, "Q": 5, "Z": 5}
# talkers after which a GP sentence is one part of a multi-constellation report
_OTHERS = frozenset("ABDILNQZ")
# talker -> (PRN offset, u-blox gnss id) for NMEA 2.x-4.0 PRNs 1..32
_SMALL_PRN = {"GA": (300, 2), "GB": (400, 3), "GI": (500, 7), "GL": (64, 6), "GQ": (192, 5),
              "BD": (400, 3), "PQ": (400, 3), "QZ": (192, 5)}  # fmt: skip
# NMEA 2.x-4.0 PRN ranges above 32: (last PRN, u-blox gnss id, svid offset, PRN offset)
_RANGES = ((64, 1, 87, 0), (96, 6, -64, 0), (119, 0, None, 0), (158, 1, 0, 0),
           (172, 0, None, 0), (182, 4, -172, 0), (192, 0, None, 0), (197, 5, -192, 0),
           (200, 0, None, 0), (237, 3, -200, 200), (300, 0, None, 0), (356, 2, -300, 0),
           (400, 0, None, 0), (437, 3, -400, 0))  # fmt: skip


def _prn_with_gnss(num: int, gnss: int) -> tuple[int, int, int]:
    """NMEA 4.10 GNSS id known: (PRN, u-blox gnss id, svid)."""
    if gnss == 1:  # GPS talker: GPS, SBAS, and receivers' own ranges
        for last, ubx, off in ((32, 0, 0), (64, 1, 87), (136, 3, -100)):
            if num <= last:
                return num, ubx, num + off
        if 152 <= num <= 157:
            return num, 1, num
        if 193 <= num <= 199:
            return num, 3, num - 192
        if 200 <= num <= 264:
            return num, 3, num - 200
        return 0, 0, 0
    if gnss == 2:
        sv = num if num < 64 else num - 64
        return 64 + sv, 6, sv
    if gnss in (3, 4):
        base, ubx = (300, 2) if gnss == 3 else (400, 3)
        sv = num
        for lo, hi, off in ((100, 200, 100), (200, 300, 200), (300, 400, 300), (400, 500, 400)):
            if lo < num < hi:
                sv = num - off
        if num >= 100 and sv == num:
            sv = 0
        return base + sv, ubx, sv
    if gnss == 5:
        sv = num if num < 100 else num - 192
        return 192 + sv, 5, sv
    if gnss == 6:
        return num + 500, 7, num
    return 0, 0, 0


def nmea_prn(talker: str, num: int, gnss: int = 0) -> tuple[int, int, int]:
    """(PRN, u-blox gnss id, svid) of an NMEA satellite number; PRN 0 when unknown."""
    if num < 1:
        return 0, 0, 0
    if gnss > 0:
        return _prn_with_gnss(num, gnss)
    if num <= 32:
        off, ubx = _SMALL_PRN.get(talker, (0, 0))
        return num + off, ubx, num
    for last, ubx, sv_off, prn_off in _RANGES:
        if num <= last:
            if sv_off is None:
                return 0, 0, 0
            return num + prn_off, ubx, num + sv_off
    return 0, 0, 0


# the 1- to 3-digit numbers (zero-padded too) -> their value: what atoi reads of them
_INTS = {f"{i:0{w}d}": i for w in (1, 2, 3) for i in range(10**w)}


def _gsa_fields(
    talker: str, f: tuple[str, ...] | list[str]
) -> tuple[int, bool, dict, tuple[int, ...]]:
    """What a GSA says, without the session: (mode, whether it sets the mode, its DOPs,
    the PRNs used). gpsd reads count - 6 PRN fields, so a NMEA 4.10 GSA (with a system
    id) reads its PDOP field as one more PRN; so does this."""
    count = len(f) + 1
    dops = {}
    if count <= 19:
        for i, name in ((14, "pdop"), (15, "hdop"), (16, "vdop")):
            v = number(f[i])
            if v is not None and v < 99.0:
                dops[name] = v
    gnss = _TALKER_GNSS.get(talker[1:2], 0)
    prns = []
    for field in f[2 : count - 4]:
        num = _INTS.get(field)
        if num is None:
            if not field:  # (an empty field: atoi's 0)
                continue
            num = atoi(field)
        if num >= 1:
            prn = nmea_prn(talker, num, gnss)[0]
            if prn > 0:
                prns.append(prn)
    mode_set = f[1][:1] != "E"
    mask = (MODE_SET if mode_set else 0) | (DOP_SET if dops else 0) | USED_IS
    return (atoi(f[1]), mode_set, dops, tuple(prns), mask)


# A satellite in the view is the message itself (immutable, so one object serves every
# epoch that repeats its fields): GpsSatellite(prn, gnss_id, sv_id, el, az, ss, used).
_satellite = positional_constructor(GpsSatellite)
_SATS: dict[tuple, tuple] = table({})  # (talker, gnss, its four fields) -> _sat_entry(...)
_WHOLES = {k: float(v) for k, v in _INTS.items()}  # (the numbers of _sat_entry)


def _sat_entry(talker: str, gnss: int, num: int, fields: tuple[str, ...] | list[str]) -> tuple:
    """One GSV satellite (``fields``: its elevation, azimuth and signal to noise, fewer at
    the end of a sentence): (PRN, whether a GSA may mark it used, the satellite not used,
    the satellite used (None when no GSA may mark it so), its (azimuth, elevation) if
    fill_dop may use them, else None). The numbers as gpsd reads them: the integer part,
    None for an empty field."""
    prn, ubx, sv = nmea_prn(talker, num, gnss)
    e, a, s = fields if len(fields) == 3 else (*fields, "", "", "")[:3]
    el, az, ss = _WHOLES.get(e), _WHOLES.get(a), _WHOLES.get(s)  # (None: "", or not read)
    if el is None and e:
        el = float(atoi(e))
    if az is None and a:
        az = float(atoi(a))
    if ss is None and s:
        ss = float(atoi(s))
    usable = prn > 0 and ss is not None and ss > 0
    seen = az is not None and 0 <= az <= 359 and el is not None and abs(el) <= 90
    return (prn, usable, _satellite(prn, ubx, sv, el, az, ss, False),
            _satellite(prn, ubx, sv, el, az, ss, True) if usable else None,
            (az, el) if seen else None)  # fmt: skip


def _gsv_fields(talker: str, f: tuple[str, ...] | list[str]) -> tuple:
    """What a GSV says, without the session: () when it has a count of fields gpsd
    refuses, else (signal id, parts, this part, satellites): one entry per satellite
    field gpsd reads, None for a PRN of 0 (which skips one field only), else
    :func:`_sat_entry`'s. The GNSS id of the talker applies to the first part only (as
    in gpsd). A receiver repeats its satellites: the last ones read are kept."""
    count = len(f) + 1
    if count <= 3 or count % 4 not in (0, 1):
        return ()
    sigid = atoi(f[-1]) if count % 4 == 1 else 0
    part = _INTS.get(f[1])
    if part is None:
        part = atoi(f[1])
    gnss = _TALKER_GNSS.get(talker[1:2], 0) if part == 1 else 0
    sats: list = []
    end = count // 4 * 4 - 1
    k = 3
    while k < end and part >= 1:
        field = f[k]
        num = _INTS.get(field)
        if num is None:
            num = atoi(field)
        k += 1
        if num == 0:
            sats.append(None)
            continue
        key = (talker, gnss, *f[k - 1 : k + 3])  # (its PRN, elevation, azimuth, signal)
        sat = _SATS.get(key)
        if sat is None:
            if len(_SATS) >= 512:
                _SATS.clear()
            sat = _SATS[key] = _sat_entry(talker, gnss, num, key[3:])
        sats.append(sat)
        k += 3
    return (sigid, atoi(f[0]), part, tuple(sats))


class Sky:
    """Satellites used (GSA) and in view (GSV), the DOPs, and GSA/GSV parsing state."""

    def __init__(self) -> None:
        self.used_prns: tuple[int, ...] = ()
        self.used_count = 0  # satellites used: GSA's list, or GGA's count when it came later
        self.view: list[GpsSatellite] = []
        # (azimuth, elevation) of the satellites used in the view whose direction is known,
        # in its order: what fill_dop computes the DOPs of
        self.geometry: list[tuple[float, float]] = []
        self.dop: dict[str, float] = {}  # xdop ydop hdop vdop pdop tdop gdop
        self.last_gsa_talker = ""
        self.last_gsv_talker = ""
        self.last_read: tuple | None = None  # what the last GSA read (_gsa_fields)
        self.seen_gsa: set[str] = set()
        self.seen_gsv: set[str] = set()
        self.part = self.awaited = 0
        self.complete = False  # a full GSV set has been seen
        self.changed = False  # since the last SKY report

    # -------------------------------------------------------------- GSA
    def gsa(self, talker: str, f: tuple[str, ...], new: dict, latch_mode: bool) -> int:
        """One GSA: mode, DOPs, satellites used. ``f`` excludes the address field."""
        read = _gsa_fields(talker, f) if len(f) + 1 >= 18 and not latch_mode else None
        if read is not None:
            new["mode"] = read[0]
        return self.gsa_read(talker, read)

    def gsa_read(self, talker: str, read: tuple | None) -> int:
        """One GSA of what :func:`_gsa_fields` read (None: too short, or after a latched
        GGA; its talker still counts); the mode it gives is ``read[0]``."""
        t = talker[1:2]
        last_last = self.last_gsa_talker
        if (
            read is not None
            and read is self.last_read
            and last_last == ""
            and self.used_prns is read[3]
            and self.used_count == len(read[3])
        ):  # the last GSA again, after other sentences: only the DOPs may have changed
            mask = read[4]
            dops = read[2]
            if dops:
                dop = self.dop
                if not dops.items() <= dop.items():
                    dop.update(dops)
                    self.changed = True
            self.last_gsa_talker = t
            if t == "P" and self.seen_gsa & _OTHERS:
                return 0
            return MODE_SET if t == "N" else mask
        mask = 0
        if read is not None:
            mode, mode_set, dops, prns, _ = read
            self.last_read = read
            if mode_set:
                mask = MODE_SET
            prev_used, prev_count = self.used_prns, self.used_count
            dop_changed = False
            if dops:
                dop = self.dop
                dop_changed = not dops.items() <= dop.items()  # (a DOP new or not the same)
                dop.update(dops)
                mask |= DOP_SET
            if last_last == "" or (t == last_last and t != "N"):
                used = prns[:MAXCHANNELS]  # (the tuple itself when it fits)
            else:
                used = prev_used + prns[: MAXCHANNELS - len(prev_used)]
            self.used_prns = used
            self.last_gsa_talker = t
            self.seen_gsa.add(t)
            self.used_count = count = len(used)
            mask |= USED_IS
            if dop_changed or prev_count != count or prev_used != used:
                self.changed = True  # a GSA repeating the last one changes nothing
        if t == "P" and self.seen_gsa & _OTHERS:
            mask = 0
        elif last_last != "N" and t == "N":
            mask = MODE_SET
        return mask

    # -------------------------------------------------------------- GSV
    def zero(self) -> None:
        self.view = []
        self.geometry = []

    def gsv(self, talker: str, f: tuple[str, ...]) -> tuple[int, bool]:
        """One GSV sentence -> (mask, more parts to come)."""
        return self.gsv_read(talker, _gsv_fields(talker, f))

    def gsv_read(self, talker: str, read: tuple) -> tuple[int, bool]:
        """One GSV of what :func:`_gsv_fields` read -> (mask, more parts to come)."""
        if not read:
            self.zero()
            return 0, False
        sigid, self.awaited, self.part, sats = read
        if self.part < 1:
            self.zero()
            return 0, False
        t = talker[1:2]
        if self.part == 1:
            if self.last_gsv_talker == "" or (t == "P" and sigid not in (2, 3, 5, 6)):
                self.zero()
            self.last_gsv_talker = t
            self.seen_gsv.add(t)
        view = self.view
        geometry = self.geometry
        used = self.used_prns
        room = MAXCHANNELS - len(view)
        for sat in sats:
            if room <= 0:
                self.zero()  # (the loop's view is still the full one, as in gpsd)
                break
            if sat is None:
                continue
            room -= 1
            if sat[1] and sat[0] in used:
                view.append(sat[3])
                if sat[4] is not None:
                    geometry.append(sat[4])
            else:
                view.append(sat[2])
        if self.part < self.awaited:
            return 0, True
        for s in view:
            if s.azimuth_deg != 0:
                break
        else:  # (no satellite with an azimuth)
            self.zero()
            return 0, False
        self.complete = True
        self.changed = True
        if t == "P" and self.seen_gsv & _OTHERS:
            return 0, False
        return SATELLITE_SET, False

    # -------------------------------------------------------------- DOPs
    def fill_dop(self) -> None:
        """DOPs from the satellites used, where the receiver gave none (gpsd fill_dop)."""
        key = tuple(self.geometry)
        dops = _DOPS.get(key)
        if dops is None:
            dops = geometry_dops(key)
            if len(_DOPS) >= 64:
                _DOPS.clear()
            _DOPS[key] = dops
        dop = self.dop
        for name, v in dops:
            if name not in dop:
                dop[name] = v


_DOPS: dict[tuple, tuple] = table({})  # the (azimuth, elevation) of the satellites used -> DOPs
