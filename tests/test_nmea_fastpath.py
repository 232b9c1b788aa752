"""The NMEA fast path (drivers/nmea/fastpath.py) is the reference path, only faster.

Every stream is fed to ``NmeaCodec()`` and to ``NmeaCodec(fast=False)`` (every sentence
through Session.parse/apply) in the same chunks; after each chunk the messages, the stats
and the whole state (session, fixes, sky, epoch bookkeeping) must be equal. Streams:
gpsd's logs (whole, in 7-byte and in random chunks), damaged copies of them (fields set
to odd values, talkers changed, lines dropped, repeated, swapped, bytes flipped; the
checksum recomputed so the damage reaches the parsers) and writer streams of fixes with
and without a position, altitude, DOPs and satellites, mixed talkers, time steps of 0,
0.2, 0.5, 1, 2 s and back, across midnight.
"""

from __future__ import annotations

import datetime as dt
import random

import pytest

from drivers.nmea import NmeaCodec, build, clear_caches
from drivers.nmea import session as session_module
from drivers.nmea.fixstate import FIELDS
from drivers.nmea.writer import epoch_sentences
from msgs import GpsFix
from tests.nmea_stream import NASTY

ODD = NASTY + ("D", "E", "1", "2", "3", "0", "4", "000000", "120000.00", "010126", "T", "K",
               " 5", "12.5", "359.9", "360.5", "-10.5", "98.9", "99.0", "0.0", "0.09")  # fmt: skip
TALKERS = ("GP", "GN", "GL", "GA", "BD", "GB", "QZ")


def _state(codec: NmeaCodec) -> tuple:
    """Everything the codec keeps from one sentence to the next, comparable."""
    comb = codec.combiner
    st = comb.session
    plain = {k: v for k, v in vars(st).items() if k not in ("fix", "lastfix", "oldfix", "sky")}
    fixes = [[getattr(f, k) for k in FIELDS] for f in (st.fix, st.lastfix, st.oldfix)]
    same = (st.lastfix is st.fix, st.oldfix is st.lastfix, st.oldfix is st.fix)
    sky = {k: v for k, v in vars(st.sky).items() if k != "view"}
    view = [tuple(getattr(s, a) for a in s.__slots__) for s in st.sky.view]
    epoch = {k: v for k, v in vars(comb).items() if k not in ("session", "_snap")}
    snap = None if comb._snap is None else [getattr(comb._snap, k) for k in FIELDS]
    return (
        sorted(plain.items()), fixes, same, sorted(sky.items()), view,
        sorted(epoch.items(), key=lambda kv: kv[0]), snap, codec.stats, codec.ignored,
    )  # fmt: skip


def _same(data: bytes, chunks: list[int] | None, rng: random.Random) -> None:
    fast, ref = NmeaCodec(), NmeaCodec(fast=False)
    i = 0
    while i < len(data):
        n = len(data) - i if chunks is None else rng.choice(chunks)
        a, b = fast.feed(data[i : i + n], i), ref.feed(data[i : i + n], i)
        assert a == b, (i, data[max(0, i - 300) : i + n])
        assert _state(fast) == _state(ref), (i, data[max(0, i - 300) : i + n])
        i += n
    assert fast.flush() == ref.flush()


def _damaged(data: bytes, rng: random.Random) -> bytes:
    out: list[bytes] = []
    for line in data.split(b"\n"):
        r = rng.random()
        body = line[1 : line.rfind(b"*")].decode("latin-1") if line[:1] == b"$" else ""
        if r < 0.03:
            continue
        elif r < 0.05:
            out += [line, line]
        elif r < 0.15 and "," in body:
            f = body.split(",")
            for _ in range(rng.randint(1, 3)):
                f[rng.randrange(1, len(f))] = rng.choice(ODD)
            if rng.random() < 0.1:
                f = f[: rng.randrange(1, len(f))]
            out.append(build(",".join(f)).rstrip(b"\n"))
        elif r < 0.17 and body[:1] == "G":
            out.append(build(rng.choice(TALKERS) + body[2:]).rstrip(b"\n"))
        elif r < 0.18 and line:
            b = bytearray(line)
            b[rng.randrange(len(b))] = rng.randrange(256)
            out.append(bytes(b))
        elif r < 0.19 and out:
            out.insert(len(out) - 1, line)
        else:
            out.append(line)
    return b"\n".join(out)


def _written(rng: random.Random, epochs: int) -> bytes:
    t = dt.datetime(2026, 11, 23, 23, 59, 50, tzinfo=dt.UTC)
    types = rng.choice([("GGA", "GSA", "RMC", "VTG", "GST", "ZDA"), ("RMC", "GGA", "GSA"),
                        ("GGA", "RMC"), ("ZDA", "GGA", "GSA", "RMC", "VTG"), ("RMC",), ("GGA",)])  # fmt: skip
    talker = rng.choice(TALKERS[:3])
    lat, lon, alt = rng.uniform(-80, 80), rng.uniform(-179, 179), rng.uniform(-50, 3000)
    out = []
    for _ in range(epochs):
        fix = GpsFix(0, lat_deg=lat, lon_deg=lon, alt_msl_m=alt if rng.random() > 0.1 else None,
                     geoid_sep_m=rng.choice([18.2, None, -30.0]),
                     mode=rng.choice([3, 3, 3, 2, 1, 0]) if rng.random() < 0.3 else 3,
                     quality=rng.choice([1, 1, 2, 4, 5]),
                     satellites=rng.choice([9, 9, 3, 2, 4, 12, 0, None]),
                     hdop=rng.choice([0.9, 1.2, None, 99.9]), pdop=rng.choice([1.6, None]),
                     vdop=rng.choice([1.3, None]), speed_mps=rng.uniform(0, 30),
                     course_deg=rng.choice([87.0, None, rng.uniform(0, 360)]), std_lat_m=1.1,
                     std_lon_m=rng.choice([1.0, None]), std_alt_m=2.0)  # fmt: skip
        step = rng.choice([1, 0.5, 0.2, 2, 0, -1]) if rng.random() < 0.2 else 1
        t += dt.timedelta(seconds=step)
        lat, lon, alt = lat + rng.uniform(-1e-4, 1e-4), lon + rng.uniform(-1e-4, 1e-4), alt + 0.1
        if rng.random() < 0.3:  # each sentence of its own talker
            out += [epoch_sentences(fix, t, rng.choice(TALKERS[:3]), (k,)) for k in types]
        else:
            out.append(epoch_sentences(fix, t, talker, types, rng.choice([4, 5, 6])))
    return b"".join(out)


@pytest.fixture
def logs(shared_dir) -> dict[str, bytes]:
    found = {p.name: p.read_bytes() for p in sorted((shared_dir / "data" / "gpsd").glob("*.log"))}
    assert found
    return found


def test_gpsd_logs_whole_and_in_chunks(logs):
    for name, data in logs.items():
        rng = random.Random(name)
        for chunks in (None, [7], [1, 5, 64, 200, 1000]):
            _same(data, chunks, rng)


def test_damaged_gpsd_logs(logs):
    rng = random.Random(7)
    for data in logs.values():
        for _ in range(20):
            _same(_damaged(data, rng), rng.choice([None, [64, 300]]), rng)


def test_written_streams_clean_and_damaged():
    rng = random.Random(11)
    for _ in range(40):
        data = _written(rng, rng.randint(3, 30))
        _same(data, rng.choice([None, [50, 700], [1, 3, 9]]), rng)
        _same(_damaged(data, rng), None, rng)


def test_the_fast_path_takes_the_usual_sentences(logs, monkeypatch):
    """Most sentences of real receivers skip the reference path (the test is not vacuous):
    counted by the calls of Session.parse, which only the reference path makes."""
    calls = [0]
    parse = session_module.Session.parse

    def counted(self, *args):
        calls[0] += 1
        return parse(self, *args)

    monkeypatch.setattr(session_module.Session, "parse", counted)
    for fast in (False, True):
        calls[0] = 0
        for data in logs.values():
            NmeaCodec(fast=fast).feed(data, 0)
        if not fast:
            decoded = calls[0]
    assert calls[0] < 0.5 * decoded, (calls[0], decoded)


def test_edge_cases_of_the_fast_path():
    """Cases each a branch of the fast path's own checks, back to back in one stream."""
    lines = [
        "GPGGA,235959.00,4500.0000,N,00700.0000,E,1,08,0.9,,M,,M,,",  # no date, no altitude
        "GPRMC,235959.00,A,4500.0000,N,00700.0000,E,0.0,0.0,311226,,",  # 11 fields, no FAA
        "GPGSA,A,240000,01,02,03,,,,,,,,,,1.6,0.9,1.3",  # a mode gpsd reads as it is
        "GPRMC,000000.00,A,4500.0001,N,00700.0001,E,0.1,12.0,010127,,,A",  # after that mode
        "GPGGA,000000.00,4500.0001,N,00700.0001,E,2,08,98.9,10.5,M,48.0,M,2.5,0123",  # DGPS
        "GPGGA,000000.00,4500.0001,N,00700.0001,E,2,08,0.9,10.5,M,48.0,M,0.05,0000",  # latched
        "GNGGA,000001.00,4500.0002,N,00700.0002,E,1,03,1.0,10.5,M,48.0,M,,",  # other talker
        "GPVTG,12.0,T,10.0,M,0.1,N,0.2,K,E",  # estimated: nothing
        "GPVTG,12.0,T,10.0,M,0.1,N,0.2,K,A",
        "GPGST,000001.00,1.0,2.0,1.5,45.0,1.1,1.2,2.1",
        "GPZDA,000001.00,01,01,2201,00,00",  # year out of range: malformed
        "GPZDA,000001.00,01,01,2027,00,00",
        "GPRMC,000001.00,A,4500.0002,N,00700.0002,E,0.1,12.0,010127,3.5,W,D",  # magvar
        "GPGGA,000002.00,4500.0003,N,00700.0003,E,1,02,1.0,,M,,M,,",  # 2 satellites: no fix
        "GPRMC,000002.00,A,4500.0003,N,00700.0003,E,,,010127,,,A",  # no speed, no track
        "GPGGA,000001.50,4500.0003,N,00700.0003,E,1,09,1.0,11.0,M,48.0,M,,",  # time goes back
    ]
    data = b"".join(build(x) for x in lines)
    for chunks in (None, [1], [40]):
        _same(data, chunks, random.Random(3))


def sky_stream(rng: random.Random, epochs: int) -> bytes:
    """Epochs of GGA, GSA, RMC, GSV sets, VTG and now and then a PSTI,030 (velocities),
    with skies of every shape: several talkers, PRNs of every range and 0, fields left
    empty, NMEA 4.10 signal ids, wrong part counts, sets of more than 130 satellites; and
    speeds and tracks that are odd (insane, unreadable, out of 0-360, with a variation)."""
    out: list[bytes] = []
    t = dt.datetime(2026, 11, 23, 23, 59, 40, tzinfo=dt.UTC)
    lat, lon = rng.uniform(-60, 60), rng.uniform(-170, 170)
    sats = [(rng.choice([rng.randint(1, 32), rng.randint(33, 437), 0]), rng.randint(-5, 92),
             rng.randint(0, 400), rng.choice(["", str(rng.randint(0, 55))]))
            for _ in range(rng.choice([3, 8, 12, 20, 140]))]  # fmt: skip
    for _ in range(epochs):
        t += dt.timedelta(seconds=rng.choice([1, 1, 1, 0.5, 0]))
        hms, ymd = t.strftime("%H%M%S.") + f"{t.microsecond // 10000:02d}", t.strftime("%d%m%y")
        lat += rng.uniform(-1e-4, 1e-4)
        la = f"{int(abs(lat)):02d}{abs(lat) % 1 * 60:08.5f},{'N' if lat >= 0 else 'S'}"
        lo = f"{int(abs(lon)):03d}{abs(lon) % 1 * 60:08.5f},{'E' if lon >= 0 else 'W'}"
        if rng.random() < 0.2:  # a sky that changes: elevation, azimuth, signal, the set
            k = rng.randrange(len(sats))
            sats[k] = (sats[k][0], rng.randint(-5, 92), rng.randint(0, 400),
                       rng.choice(["", str(rng.randint(0, 55))]))  # fmt: skip
        used = [p for p, *_ in sats if rng.random() < 0.7][: rng.choice([12, 12, 20])]
        dops = [rng.choice(["1.6", "2.1", "", "99.0"]) for _ in range(3)]
        speed = rng.choice(["0.52", "1.7", f"{rng.uniform(0, 40):.2f}", "", "abc", "99999.9"])
        track = rng.choice(["87.0", f"{rng.uniform(0, 360):.1f}", "400.5", "-20.0", ""])
        var = rng.choice(["", "", "3.5,W", "1.2,E"])
        body = [f"GPGGA,{hms},{la},{lo},1,{len(used):02d},{dops[1] or '0.9'},38.5,M,18.2,M,,",
                f"{rng.choice(['GP', 'GN', 'GL'])}GSA,A,{rng.choice([3, 3, 2, 1])},"
                + ",".join(f"{p:02d}" for p in used) + ",," * max(0, 12 - len(used))
                + ",".join(dops) + rng.choice(["", ",1"]),
                f"GPRMC,{hms},A,{la},{lo},{speed},{track},{ymd},{var or ','},A"]  # fmt: skip
        for talker in rng.sample(["GP", "GL", "GA", "BD"], rng.randint(1, 2)):
            view = [s for s in sats if rng.random() < 0.9]
            parts = [view[i : i + 4] for i in range(0, len(view), 4)] or [[]]
            total = len(parts) + rng.choice([0, 0, 0, 1, -1])
            for n, part in enumerate(parts, 1):
                fields = ",".join(f"{p:02d},{el},{az:03d},{ss}" for p, el, az, ss in part)
                sig = rng.choice(["", "", ",1", ",7"])
                body.append(f"{talker}GSV,{total},{n},{len(view):02d},{fields}{sig}".rstrip(","))
        body.append(f"GPVTG,{track},T,{rng.choice(['', '80.5'])},M,{speed},N,1.0,K,A")
        if rng.random() < 0.2:
            vel = ",".join(rng.choice(["0.10", "-0.20", "", "1e5"]) for _ in range(3))
            body.append(f"PSTI,030,{hms},A,{la},{lo},38.5,{vel},{ymd},A,0.0,0.0")
        out += [build(b) for b in body if rng.random() < 0.97]
    return b"".join(out)


def test_random_skies_speeds_and_tracks():
    """GSV sets of every shape, velocities, and speeds and tracks that change alone or
    are odd: the fast readers (GSV's, and the error model run on a change of speed or
    track alone) leave what the reference leaves."""
    rng = random.Random(23)
    for _ in range(25):
        data = sky_stream(rng, rng.randint(3, 25))
        _same(data, rng.choice([None, [40, 500], [1, 7, 64]]), rng)
        _same(_damaged(data, rng), None, rng)


def test_hostile_bytes_are_counted_and_skipped():
    """Bytes of any value, cut lines and runs of sentences glued together: both paths
    count and skip the same, never raise, and agree on everything they decode."""
    rng = random.Random(29)
    clean = sky_stream(rng, 12) + _written(rng, 12)
    for _ in range(30):
        data = bytearray(clean)
        for _ in range(rng.randint(1, 60)):
            i = rng.randrange(len(data))
            r = rng.random()
            if r < 0.5:
                data[i] = rng.randrange(256)
            elif r < 0.7:
                del data[i : i + rng.randint(1, 80)]
            elif r < 0.85:
                data[i:i] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 200)))
            else:
                data[i:i] = rng.choice([b"\n", b"\r\n", b"$", b"*", b",", b"$GPGGA,", b"*00\r\n"])
        codec = NmeaCodec()
        _same(bytes(data), rng.choice([None, [3, 600], [40, 250]]), rng)
        codec.feed(bytes(data), 0)
        assert codec.stats.frames_ok <= bytes(data).count(b"$")


def test_tables_change_no_result(logs):
    """The readers' tables of read fields (drivers/nmea/memo.py) only make reading
    faster: emptied between every chunk, the messages and the state are the same."""
    rng = random.Random(31)
    streams = [*logs.values(), sky_stream(rng, 20), _written(rng, 20)]
    for data in streams:
        warm, cold = NmeaCodec(), NmeaCodec()
        for i in range(0, len(data), 97):
            a = warm.feed(data[i : i + 97], i)
            clear_caches()
            assert cold.feed(data[i : i + 97], i) == a
            assert _state(cold) == _state(warm)
        assert warm.flush() == cold.flush()


def _with_gll(data: bytes, rng: random.Random, only: bool = False) -> bytes:
    """A GLL of each GGA's time and position (valid or not, FAA modes of every kind)
    beside it, or (``only``) in its place, the RMC and VTG left out too."""
    out = []
    for line in data.split(b"\n"):
        body = line[1 : line.rfind(b"*")].decode("latin-1") if line[:1] == b"$" else ""
        f = body.split(",")
        if body[2:5] == "GGA" and len(f) >= 6:
            gll = f"{body[:2]}GLL,{f[2]},{f[3]},{f[4]},{f[5]},{f[1]},{rng.choice('AAAV')}"
            if rng.random() < 0.8:
                gll += "," + rng.choice(["A", "D", "N", "E", "", "R"])
            gll_line = build(gll).rstrip(b"\n")
            out += [gll_line] if only else rng.choice([[gll_line, line], [line, gll_line]])
        elif not only or body[2:5] in ("GSA", "GSV", "ZDA"):
            out.append(line)
    return b"\n".join(out)


def test_gll_beside_gga_and_alone(logs):
    """The GLL of an epoch under way takes the fast path (one that starts a cycle, the
    reference): gpsd's logs and written streams with a GLL beside each GGA, or alone."""
    rng = random.Random(37)
    streams = [*logs.values()] + [_written(rng, rng.randint(3, 30)) for _ in range(20)]
    for data in streams:
        for only in (False, True):
            gll = _with_gll(data, rng, only)
            _same(gll, rng.choice([None, [7], [40, 500]]), rng)
            _same(_damaged(gll, rng), None, rng)
