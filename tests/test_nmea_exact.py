"""The NMEA readers' shortcuts give what the plain computation gives, bit for bit.

Each shortcut of the fast readers is checked against the straightforward computation it
replaces, written out here: a time field read through tables (and its value as a number
from its digits), a position's whole minutes looked up and its fraction from its digits,
the DOPs of a geometry (the normal matrix and its Gauss-Jordan inverse, once with a
lambda and generator sums), the sky's geometry kept as a GSV set is read, the framer's
address keys and its keyed routing, and the bound that spares the distance. Inputs: edge
cases and seeded random fields, geometries (degenerate ones too) and streams.
"""

from __future__ import annotations

import math
import random
import re

from drivers.nmea import NmeaCodec, build, clear_caches, fastpath
from drivers.nmea.dops import geometry_dops
from drivers.nmea.errmodel import _nearer_than, earth_distance
from drivers.nmea.fields import _degrees, clock, fnum, latlon, read_number
from drivers.nmea.framer import NmeaFramer, _classify, _key
from tests.test_nmea_fastpath import sky_stream

_INT = re.compile(r"\s*([-+]?\d+)")


def _hhmmss_plain(s: str) -> int | None:
    """``hhmmss[.fff]`` in ns, the plain way (the fraction's digits, up to 9, as ns)."""
    head = s[:6]
    if len(head) < 6 or not (head.isdigit() and head.isascii()):
        return None
    h, m, sec = int(head[:2]), int(head[2:4]), int(head[4:6])
    if h > 23 or m > 59 or sec > 60:
        return None
    ns = 0
    if s[6:7] == "." and s[7:8].isdigit() and len(s) - 7 <= 9:
        lead = _INT.match(s[7:])
        ns = int(lead.group(1)) * 10 ** (9 - (len(s) - 7)) if lead else 0
    return ((h * 60 + m) * 60 + sec) * 1_000_000_000 + ns


def _degrees_plain(field: str) -> float | None:
    """gpsd's decode_lat_or_lon: whole minutes as an integer, the fraction added once."""
    whole, dot, frac = field.partition(".")
    if not dot:
        return None
    m = _INT.match(whole)
    if m is None or m.end() != len(whole):
        if whole:
            return None
        minutes = 0
    else:
        minutes = int(m.group(1))
    minutes -= int(minutes / 100) * 40
    f = fnum("." + frac) if frac else 0.0
    return None if f is None else (minutes + f) * (1.0 / 60.0)


def _fields(rng: random.Random) -> list[str]:
    odd = "0123456789.....-+ eE_xN*" + "\u0663"
    cases = ["", ".", "0", "123456", "123456.", "235960.123456789", "235960.1234567891",
             "240000", "236000.00", "3733.99000", "12658.67880", ".5", "-3733.5", "+3733.5",
             "3733.5e3", "3733.9_9", " 3733.5", "3733.\u0663", "0000.0000", "18000.0000",
             "123456.1a", "123456.5 ", "4404.1237962", "1.", "123456." + "7" * 30]  # fmt: skip
    for _ in range(20000):
        cases.append("".join(rng.choice(odd) for _ in range(rng.randint(0, 14))))
        cases.append(f"{rng.randint(0, 99):02d}{rng.randint(0, 99):02d}{rng.randint(0, 99):02d}"
                     + rng.choice(["", ".", ".0", ".5", ".123", ".1234567890", ".12a", "a",
                                   "." + str(rng.randint(0, 10 ** rng.randint(0, 25)))]))  # fmt: skip
        cases.append(f"{rng.randint(0, 18000)}." + str(rng.randint(0, 10 ** rng.randint(0, 12))))
    return cases


def test_times_and_positions_read_exactly():
    for s in _fields(random.Random(1)):
        for _ in range(2):  # the tables empty, then filled
            assert repr(clock(s)) == repr((_hhmmss_plain(s), fnum(s))), s
            assert repr(_degrees(s)) == repr(_degrees_plain(s)), s


def test_the_readers_tables_read_as_the_plain_functions():
    """What the fast path reads a new field through (fastpath._time, fields.read_number,
    fields.latlon, each with the usual field's reading written out) is what clock, fnum
    and _degrees read, tables empty and filled."""
    clear_caches()
    fields = _fields(random.Random(3))
    for k, s in enumerate(fields):
        other = fields[k - 1]
        for _ in range(2):
            assert repr(fastpath._TIMES.get(s) or fastpath._time(s)) == repr(clock(s)), s
            assert repr(read_number(s)) == repr(fnum(s)), s
            a, b = _degrees_plain(s), _degrees_plain(other)
            want = None if a is None or b is None or not s or not other else (-a, b)
            assert repr(latlon(s, "S", other, "E")) == repr(want), (s, other)
        if k % 500 == 0:
            clear_caches()


def _dops_plain(az_el: tuple[tuple[float, float], ...]) -> tuple[tuple[str, float], ...]:
    rows = []
    for az, el in az_el:
        a, e = math.radians(az), math.radians(el)
        rows.append((math.sin(a) * math.cos(e), math.cos(a) * math.cos(e), math.sin(e), 1.0))
    if len(rows) < 4:
        return ()
    m = [[sum(r[i] * r[j] for r in rows) for j in range(4)] for i in range(4)]
    a = [row[:] + [1.0 if i == j else 0.0 for j in range(4)] for i, row in enumerate(m)]
    for c in range(4):
        p = max(range(c, 4), key=lambda r: abs(a[r][c]))
        if abs(a[p][c]) < 1e-12:
            return ()
        a[c], a[p] = a[p], a[c]
        piv = a[c][c]
        a[c] = [x / piv for x in a[c]]
        for r in range(4):
            if r != c and a[r][c] != 0.0:
                k = a[r][c]
                a[r] = [x - k * y for x, y in zip(a[r], a[c], strict=True)]
    d = [a[i][4 + i] for i in range(4)]
    dops = {"xdop": d[0], "ydop": d[1], "hdop": d[0] + d[1], "vdop": d[2],
            "pdop": d[0] + d[1] + d[2], "tdop": d[3], "gdop": d[0] + d[1] + d[2] + d[3]}  # fmt: skip
    return tuple((k, math.sqrt(v)) for k, v in dops.items() if v >= 0.0)


def test_dops_of_a_geometry_bit_for_bit():
    rng = random.Random(2)
    for _ in range(3000):
        n = rng.randint(0, 14)
        kind = rng.random()
        if kind < 0.4:
            g = [(rng.randint(0, 359), rng.randint(-90, 90)) for _ in range(n)]
        elif kind < 0.7:  # nearly or exactly singular: one direction repeated, one plane
            az, el = rng.randint(0, 359), rng.randint(0, 90)
            g = [(az if rng.random() < 0.8 else rng.randint(0, 359), el) for _ in range(n)]
        else:
            g = [(rng.choice([0, 90, 180, 270]), rng.choice([0, 45, 90, -90])) for _ in range(n)]
        az_el = tuple((float(a), float(e)) for a, e in g)
        assert repr(geometry_dops(az_el)) == repr(_dops_plain(az_el)), az_el


def test_the_sky_geometry_is_that_of_the_satellites_used():
    """What fill_dop computes the DOPs of, kept as the view is read: the used satellites
    with a known direction, in the view's order."""
    rng = random.Random(3)
    for _ in range(10):
        data = sky_stream(rng, 15)
        codec = NmeaCodec()
        for i in range(0, len(data), 61):
            codec.feed(data[i : i + 61], 0)
            sky = codec.combiner.session.sky
            assert sky.geometry == [
                (s.azimuth_deg, s.elevation_deg)
                for s in sky.view
                if s.used and s.prn >= 1 and s.azimuth_deg is not None
                and 0 <= s.azimuth_deg <= 359 and s.elevation_deg is not None
                and abs(s.elevation_deg) <= 90
            ]  # fmt: skip


def test_the_framer_routes_by_key_as_by_address():
    """Runs checked at once (numpy, keys from the bytes after each "$") and line by line
    give the same sentences and counts, for addresses of every length, without a comma,
    empty, or with a comma too early or too late to be the usual one."""
    rng = random.Random(4)
    bodies = ["GPGGA,1,2", "PSTI,030,1", "GPGSAXX,1", "A,1", "AB,", ",1", "ABCDEFG,1",
              "ABCDEFGH,1", "GPGGA", "GP,GA,1", "GPGGA,", "GPRMC,,,,", "P,1", "GPGG,,1"]  # fmt: skip
    noise = [b"x\r\n", b"\r\n", b"$GPGGA,1*00\r\n", b"$GPGGA,12$GPRMC,1*2D\r\n"]
    for _ in range(200):
        lines = [
            build(rng.choice(bodies)) if rng.random() < 0.9 else rng.choice(noise)
            for _ in range(rng.randint(1, 60))
        ]
        data = b"".join(lines)
        whole, by_line = NmeaFramer(), NmeaFramer()
        a = whole.feed_raw(data)
        b = [s for line in lines for s in by_line.feed_raw(line)]
        assert a == b and whole.stats == by_line.stats, data
        if len(data) >= 512:  # (what the framer checks with numpy)
            text = data[: data.rfind(b"\n")].decode("ascii")
            starts, ends, _, lengths, keys = _classify(text.encode("ascii"), 128)
            for s, e, n, k in zip(starts.tolist(), ends.tolist(), lengths.tolist(),
                                  keys.tolist(), strict=True):  # fmt: skip
                address, comma, _ = text[s + 1 : e - 3].partition(",")
                if n > 0:
                    assert comma and n == len(address) and k == _key(address)
                else:
                    assert k == -1


def test_the_distance_bound_holds():
    """Two points the bound calls nearer than d are no further apart than d (Vincenty's
    distance), near the poles and across the antimeridian too."""
    rng = random.Random(5)
    checked = 0
    for _ in range(20000):
        lat = rng.choice([rng.uniform(-90, 90), rng.uniform(85, 90), rng.uniform(-1, 1)])
        lon = rng.choice([rng.uniform(-180, 180), rng.uniform(179, 180)])
        step = 10 ** rng.uniform(-7, -2)
        lat2 = max(-90.0, min(90.0, lat + rng.uniform(-step, step)))
        lon2 = (lon + rng.uniform(-step, step) + 180.0) % 360.0 - 180.0
        d = 10 ** rng.uniform(-2, 3)
        if _nearer_than(lat, lon, lat2, lon2, d):
            dist = earth_distance(lat, lon, lat2, lon2)
            assert dist is not None and dist <= d, (lat, lon, lat2, lon2, d, dist)
            checked += 1
    assert checked > 1000
    assert not _nearer_than(None, 0.0, 0.0, 0.0, 1e9)
