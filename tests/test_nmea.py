"""NMEA codec: round trips through the writer, framing errors counted and skipped, resync."""

from __future__ import annotations

import datetime as dt

from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.nmea import Datum, NmeaCodec, build, xor_checksum
from drivers.nmea.epoch import iso_time
from drivers.nmea.session import Session
from drivers.nmea.writer import epoch_sentences
from msgs import GpsFix, GpsSky

T0 = dt.datetime(2026, 11, 22, 20, 0, 0, tzinfo=dt.UTC)


def _fix(lat, lon, alt=12.5, mode=3, **kw) -> GpsFix:
    base = dict(
        stamp_ns=0,
        lat_deg=lat,
        lon_deg=lon,
        alt_msl_m=alt,
        geoid_sep_m=20.0,
        mode=mode,
        quality=1,
        satellites=9,
        hdop=0.9,
        pdop=1.6,
        vdop=1.3,
        speed_mps=1.25,
        course_deg=87.5,
        std_lat_m=1.5,
        std_lon_m=1.6,
        std_alt_m=2.5,
    )
    base.update(kw)
    return GpsFix(**base)


def _run(codec: NmeaCodec, data: bytes, chunk: int = 17) -> list[GpsFix]:
    """The fixes of a stream fed in chunks (the skies are checked separately)."""
    return [m for m in _messages(codec, data, chunk) if isinstance(m, GpsFix)]


def _messages(codec: NmeaCodec, data: bytes, chunk: int = 17) -> list[GpsFix | GpsSky]:
    out = []
    for i in range(0, len(data), chunk):
        out += codec.feed(data[i : i + chunk], i)
    return out + codec.flush()


def test_checksum_of_a_known_sentence():
    line = "GPGGA,030719.000,3747.0873,S,17518.8938,E,1,08,1.1,59.9,M,23.7,M,,0000"
    assert f"{xor_checksum(line):02X}" == "7D"
    assert build(line).endswith(b"*7D\r\n")


@settings(max_examples=100, deadline=None)
@given(
    lat=st.floats(-89.9, 89.9),
    lon=st.floats(-179.9, 179.9),
    alt=st.floats(-100, 5000),
    talker=st.sampled_from(["GP", "GN", "GL", "GA", "GB", "BD"]),
    ms=st.integers(0, 86_399_990).map(lambda x: x - x % 10),
)
def test_round_trip(lat, lon, alt, talker, ms):
    when = T0.replace(hour=0, minute=0) + dt.timedelta(milliseconds=ms)
    data = epoch_sentences(_fix(lat, lon, alt), when, talker=talker, decimals=6)
    (fix,) = _run(NmeaCodec(), data)
    assert fix.mode == 3 and fix.talker == talker
    assert abs(fix.lat_deg - lat) < 1e-7 and abs(fix.lon_deg - lon) < 1e-7
    assert abs(fix.alt_msl_m - alt) <= 0.005 + 1e-9  # 2 decimals, plus float rounding
    assert fix.time_utc == when.strftime("%Y-%m-%dT%H:%M:%S.") + f"{ms % 1000:03d}Z"
    assert fix.satellites == 9 and fix.hdop == 0.9 and fix.pdop == 1.6 and fix.vdop == 1.3
    assert abs(fix.speed_mps - 1.25) < 1e-3 and fix.course_deg == 87.5
    assert (fix.std_lat_m, fix.std_lon_m, fix.std_alt_m) == (1.5, 1.6, 2.5)
    assert fix.geoid_sep_m == 20.0 and fix.east_m == 0.0 and fix.north_m == 0.0


def test_epochs_are_reported_as_soon_as_the_cycle_ender_arrives():
    codec = NmeaCodec()
    fixes = []
    for k in range(3):
        data = epoch_sentences(_fix(45.0 + k * 1e-5, 7.0), T0 + dt.timedelta(seconds=k))
        fixes.append([m for m in codec.feed(data, k) if isinstance(m, GpsFix)])
    # the first epoch is reported when the second starts; from then on at once, when the
    # sentence type that ended the first epoch (ZDA) arrives
    assert [len(f) for f in fixes] == [0, 2, 1]
    assert fixes[1][1].time_utc == "2026-11-22T20:00:01.000Z"
    assert fixes[2][0].time_utc == "2026-11-22T20:00:02.000Z"
    assert [m for m in codec.flush() if isinstance(m, GpsFix)] == []  # nothing pending
    last = fixes[2][0]
    assert abs(last.north_m - 2 * 1e-5 * 111_132) < 0.1  # datum = first fix


def test_local_metres_about_a_configured_datum():
    d = Datum(44.0, -121.0)
    e, n = d.to_local(44.001, -120.999)
    assert abs(n - 111.1) < 0.2 and abs(e - 80.2) < 0.2
    lat, lon = d.to_geodetic(e, n)
    assert abs(lat - 44.001) < 1e-12 and abs(lon + 120.999) < 1e-12
    codec = NmeaCodec(datum=d)
    (fix,) = _run(codec, epoch_sentences(_fix(44.001, -120.999), T0))
    assert abs(fix.east_m - e) < 0.01 and abs(fix.north_m - n) < 0.01


def test_no_fix_epoch():
    (fix,) = _run(NmeaCodec(), epoch_sentences(_fix(None, None, mode=1), T0))
    assert fix.mode == 1 and fix.lat_deg is None and fix.time_utc.startswith("2026-11-22")


def test_missing_checksum_only_when_configured():
    line = b"$GPGGA,120000.00,4500.0000,N,00700.0000,E,1,08,1.0,100.0,M,,M,,\r\n"
    rmc = b"$GPRMC,120000.00,A,4500.0000,N,00700.0000,E,0.0,0.0,010126,,,A\r\n"
    strict = NmeaCodec()
    assert _run(strict, line + rmc) == [] and strict.framer.no_checksum == 2
    (fix,) = _run(NmeaCodec(require_checksum=False), line + rmc)
    assert fix.mode == 3 and fix.lat_deg == 45.0 and fix.time_utc == "2026-01-01T12:00:00.000Z"


def test_garbage_is_counted_and_skipped():
    good = epoch_sentences(_fix(10.0, 20.0), T0)
    bad_ck = build("GPGGA,200000.00,1000.0000,N,02000.0000,E,1,08,1.0,1.0,M,,M,,")[:-5]
    noise = bytes(range(256)) + b"\n" + b"$GPGGA,\x00\xff\x13,12*00\r\n"
    overlong = b"$GPTXT," + b"A" * 300 + b"*00\r\n"
    cut = good[:30]  # a sentence cut short, then the next one starts
    codec = NmeaCodec()
    fixes = _run(codec, noise + overlong + bad_ck + b"*00\r\n" + cut + good, chunk=7)
    assert len(fixes) == 1 and fixes[0].lat_deg == 10.0
    assert codec.stats.bad_checksums == 1
    assert codec.framer.overlong >= 1 and codec.framer.noisy >= 1
    assert codec.stats.bytes_skipped > 300


@settings(max_examples=100, deadline=None)
@given(noise=st.binary(max_size=200), cut=st.integers(0, 400), chunk=st.integers(1, 64))
def test_corruption_never_crashes_and_resyncs_within_one_sentence(noise, cut, chunk):
    e1 = epoch_sentences(_fix(10.0, 20.0), T0)
    e2 = epoch_sentences(_fix(10.5, 20.5), T0 + dt.timedelta(seconds=1))
    e3 = epoch_sentences(_fix(11.0, 21.0), T0 + dt.timedelta(seconds=2))
    # damage: noise, then epoch 1 cut anywhere, then a lone newline-free tail
    stream = noise + e1[: cut % len(e1)] + b"\r\n" + e2 + e3
    fixes = _run(NmeaCodec(), stream, chunk)
    good = [f for f in fixes if f.lat_deg in (10.5, 11.0)]
    assert [f.lat_deg for f in good][-2:] == [10.5, 11.0]
    assert good[-1].mode == 3 and good[-1].time_utc == "2026-11-22T20:00:02.000Z"


def test_zda_past_year_9999_is_counted_not_raised():
    codec = NmeaCodec()
    codec.feed(b"$GPZDA,235960.00,31,12,9999,00,00*6C\r\n", 0)
    assert codec.flush() == [] and codec.malformed == 1 and codec.stats.malformed == 1
    # a date past year 9999 (rollover correction of a far date) gives no time, no error
    session = Session(rollover_before_year=9999)
    session.set_date((9998, 12, 31))
    assert session.merge_hhmmss("235959.99")
    assert iso_time(session.time_ns()) == ""
    assert iso_time(None) == "" and iso_time(0) == "1970-01-01T00:00:00.000Z"


def test_zda_with_an_implausible_year_gives_no_date():
    """A 2-digit year (49) is not guessed into a century: the sentence is malformed."""
    gga = build("GPGGA,120000.00,4500.0000,N,00700.0000,E,1,08,1.0,100.0,M,,M,,")
    for year in ("49", "0049", "1899", "2201", "20x6"):
        codec = NmeaCodec()
        zda = build(f"GPZDA,120000.00,01,01,{year},00,00")
        (fix,) = _run(codec, gga + zda)
        assert fix.time_utc == "" and codec.stats.malformed == 1, year
    (fix,) = _run(NmeaCodec(), gga + build("GPZDA,120000.00,01,01,2049,00,00"))
    assert fix.time_utc == "2049-01-01T12:00:00.000Z"


def test_a_sentence_of_the_maximum_length_split_between_cr_and_lf_is_kept():
    body = "GPTXT,01,01,02,"
    body += "X" * (128 - len(build(body)) + 2)  # 128 bytes from '$' to the checksum
    line = build(body)
    assert len(line) == 128 + 2
    codec = NmeaCodec()
    codec.feed(line[:-1], 0)
    codec.feed(line[-1:], 1)
    assert codec.stats.frames_ok == 1 and codec.framer.overlong == 0 and codec.ignored == 1
    codec.feed(build(body + "X")[:-1], 2)  # one byte over: dropped
    assert codec.framer.overlong == 1
