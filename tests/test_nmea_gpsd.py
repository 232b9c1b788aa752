"""gpsd's rules in the NMEA codec, one test per rule: mode, GLL/GNS receivers, the last
sentence's position, PGRMZ, GSV into GpsSky, GST, ZDA's time, error estimates and climb."""

from __future__ import annotations

import json

import pytest

from drivers.nmea import NmeaCodec, build
from msgs import GpsFix, GpsSky, decode, encode

RMC_DATE = "GPRMC,120000.00,A,4500.0000,N,00700.0000,E,0.0,0.0,010126,,,A"


def run(*bodies: str) -> tuple[list[GpsFix], list[GpsSky]]:
    """Sentences (without ``$`` and checksum) through a codec: its fixes and skies."""
    codec = NmeaCodec()
    out = codec.feed(b"".join(build(b) for b in bodies), 0) + codec.flush()
    assert codec.malformed == 0
    return [m for m in out if isinstance(m, GpsFix)], [m for m in out if isinstance(m, GpsSky)]


def last_fix(*bodies: str) -> GpsFix:
    return run(*bodies)[0][-1]


def test_gsa_decides_the_mode_over_a_gga_without_satellites():
    fix = last_fix(
        RMC_DATE,
        "GNGGA,120001.00,4500.0000,N,00700.0000,E,2,00,0.9,100.0,M,47.0,M,,",
        "GNGSA,A,3,01,02,03,04,05,,,,,,,,1.6,0.9,1.3",
    )
    assert fix.mode == 3 and fix.status == 2 and fix.alt_msl_m == 100.0
    assert fix.alt_hae_m == pytest.approx(147.0)


def test_gga_alone_is_no_fix_with_fewer_than_three_satellites():
    fix = last_fix(RMC_DATE, "GPGGA,120001.00,4500.0000,N,00700.0000,E,1,02,0.9,100.0,M,47.0,M,,")
    assert fix.mode == 1 and fix.lat_deg is None and fix.time_utc.endswith("12:00:01.000Z")


def test_a_gll_only_receiver_gives_fixes():
    fixes, _ = run(
        "GPGLL,4500.0000,N,00700.0000,E,120000.00,A,A",
        "GPGLL,4500.0060,N,00700.0000,E,120001.00,A,A",
        "GPGLL,4500.0120,N,00700.0000,E,120002.00,V,N",
    )
    assert [f.mode for f in fixes] == [2, 2, 1]
    assert fixes[1].lat_deg == pytest.approx(45.0001) and fixes[2].lat_deg is None
    assert fixes[0].time_utc == ""  # no date without RMC or ZDA


def test_a_gns_only_receiver_gives_3d_fixes_with_dgps():
    fix = last_fix(
        "GPZDA,224749.00,01,02,2026,00,00",
        "GPGNS,224749.00,3333.4268304,N,11153.3538273,W,D,19,0.6,406.110,-26.294,6.0,0138,S",
    )
    assert fix.mode == 3 and fix.status == 2 and fix.time_utc == "2026-02-01T22:47:49.000Z"
    assert fix.lat_deg == pytest.approx(33 + 33.4268304 / 60, abs=1e-12)
    assert fix.alt_msl_m == 406.11 and fix.alt_hae_m == pytest.approx(379.816)
    assert (fix.dgps_age_s, fix.dgps_station, fix.hdop) == (6.0, 138, 0.6)
    assert fix.eph_m == pytest.approx(0.6 * 4.75)  # DGPS: a quarter of gpsd's UERE


def test_the_last_sentence_of_an_epoch_gives_the_position():
    fix = last_fix(
        "GPGGA,120000.00,4500.0000,N,00700.0000,E,1,08,0.9,100.0,M,47.0,M,,",
        "GPRMC,120000.00,A,4500.00012,N,00700.00034,E,0.0,0.0,010126,,,A",
    )
    assert fix.lat_deg == pytest.approx(45 + 0.00012 / 60, abs=1e-12)
    assert fix.lon_deg == pytest.approx(7 + 0.00034 / 60, abs=1e-12)


def test_pgrmz_gives_the_altitude_in_feet_and_the_mode():
    fix = last_fix(RMC_DATE, "PGRMZ,246,f,3")
    assert fix.mode == 3 and fix.alt_msl_m == pytest.approx(246 * 0.3048)


def test_gsv_sets_make_a_sky_with_used_satellites_and_computed_dops():
    _, skies = run(
        RMC_DATE,
        "GPGSA,A,3,17,28,06,01,,,,,,,,,1.8,1.1,1.5",
        "GPGSV,2,1,05,17,72,207,32,28,59,095,31,06,35,347,25,01,29,132,23",
        "GPGSV,2,2,05,30,23,011,",
        "GLGSV,1,1,01,02,45,100,30",
        "GBGSV,1,1,01,11,12,200,20",
    )
    sky = skies[-1]
    assert sky.n_sat == 7 and sky.u_sat == 4
    assert [s.prn for s in sky.satellites] == [17, 28, 6, 1, 30, 66, 411]
    assert [s.used for s in sky.satellites] == [True] * 4 + [False] * 3
    assert sky.satellites[4].snr_dbhz is None and sky.satellites[5].gnss_id == 6
    assert (sky.hdop, sky.pdop, sky.vdop) == (1.1, 1.8, 1.5)  # the receiver's own DOPs
    assert sky.xdop is not None and sky.gdop is not None and sky.gdop > sky.pdop


def test_an_incomplete_gsv_set_is_not_a_sky():
    _, skies = run(RMC_DATE, "GPGSV,2,1,05,17,72,207,32,28,59,095,31,06,35,347,25,01,29,132,23")
    assert all(s.n_sat is None for s in skies)


def test_gst_in_full():
    fix = last_fix(RMC_DATE, "GPGST,120000.00,1.3,105.1,9.1,-40.9,0.3,0.4,0.6")
    assert (fix.gst_rms_m, fix.gst_major_m, fix.gst_minor_m, fix.gst_orient_deg) == (
        1.3, 105.1, 9.1, -40.9,
    )  # fmt: skip
    assert (fix.std_lat_m, fix.std_lon_m, fix.std_alt_m) == (0.3, 0.4, 0.6)


def test_zda_gives_the_time_as_well_as_the_date():
    fix = last_fix(
        "GPGGA,120000.50,4500.0000,N,00700.0000,E,1,08,0.9,100.0,M,47.0,M,,",
        "GPZDA,120000.50,01,02,2026,00,00",
    )
    assert fix.time_utc == "2026-02-01T12:00:00.500Z" and fix.ept_s == 0.005


def test_climb_and_error_estimates_over_two_epochs():
    fixes, _ = run(
        "GPGGA,120000.00,4500.0000,N,00700.0000,E,1,08,1.1,100.0,M,47.0,M,,",
        "GPGSA,A,3,01,02,03,04,05,06,07,08,,,,,1.8,1.1,1.5",
        "GPRMC,120000.00,A,4500.0000,N,00700.0000,E,1.0,90.0,010126,2.5,W,A",
        "GPGGA,120002.00,4500.0000,N,00700.0000,E,1,08,1.1,101.0,M,47.0,M,,",
        "GPGSA,A,3,01,02,03,04,05,06,07,08,,,,,1.8,1.1,1.5",
        "GPRMC,120002.00,A,4500.0000,N,00700.0000,E,1.0,90.0,010126,2.5,W,A",
    )
    first, second = fixes
    assert first.climb_mps is None and second.climb_mps == pytest.approx(0.5)
    assert second.eph_m == pytest.approx(1.1 * 19) and second.epv_m == pytest.approx(1.5 * 23)
    assert second.sep_m == pytest.approx(1.8 * 19) and second.epc_mps == pytest.approx(34.5)
    assert second.magvar_deg == -2.5 and second.magtrack_deg == pytest.approx(87.5)
    assert second.speed_mps == pytest.approx(1852 / 3600) and second.course_deg == 90.0


def test_vtg_modes_e_and_n_give_nothing():
    fix = last_fix(RMC_DATE, "GPVTG,45.0,T,,M,2.0,N,3.7,K,N")
    assert fix.course_deg == 0.0 and fix.speed_mps == 0.0


def test_skytraq_psti030_gives_the_velocity():
    fix = last_fix(
        "PSTI,030,232713.000,A,4404.1237969,N,12118.8472448,W,1132.560,-0.01,0.03,0.02,"
        "280316,D,0.0,0.0"
    )
    assert fix.mode == 3 and fix.status == 2 and fix.time_utc == "2016-03-28T23:27:13.000Z"
    assert (fix.vel_n_mps, fix.vel_e_mps, fix.vel_d_mps) == (0.03, -0.01, -0.02)
    assert fix.climb_mps == 0.02 and fix.speed_mps == pytest.approx(0.0316, abs=1e-4)


def test_garmin_pgrmf_gives_the_leap_seconds():
    fix = last_fix(
        RMC_DATE, "PGRMF,290,293895,010126,120000,18,4500.0000,N,00700.0000,E,A,2,0,226,2,1"
    )
    assert fix.leap_seconds == 18 and fix.mode == 3


def test_a_gps_fix_of_an_old_log_still_decodes():
    old = {"stamp_ns": 5, "time_utc": "", "lat_deg": 1.0, "lon_deg": 2.0, "mode": 3}
    fix = decode(GpsFix, json.dumps(old).encode())
    assert fix.lat_deg == 1.0 and fix.status == 0 and fix.alt_hae_m is None
    sky = GpsSky(1, satellites=(), n_sat=0, u_sat=0)
    assert decode(GpsSky, encode(sky)) == sky


def test_an_epoch_without_gga_does_not_keep_the_last_ggas_quality():
    fixes, _ = run(
        "GPGGA,120000.00,4500.0000,N,00700.0000,E,2,08,0.9,100.0,M,47.0,M,,",
        RMC_DATE,
        "GPRMC,120001.00,A,4500.0000,N,00700.0000,E,0.0,0.0,010126,,,A",
    )
    # the satellites used stay (gpsd's count persists until a GGA or GSA changes it)
    assert [(f.quality, f.satellites) for f in fixes] == [(2, 8), (1, 8)]


def test_every_handler_gives_a_fix_field_only_with_its_mask_bit(shared_dir):
    """merge() copies the fix fields a sentence gives without looking at the mask: that
    holds while every handler sets a field's bit (fixstate.GATE) whenever it gives it.
    Checked on the sentences of gpsd's logs and on copies with fields set to odd values."""
    import random

    from drivers.nmea.codec import NmeaFramer
    from drivers.nmea.fixstate import GATE, SPECIAL
    from drivers.nmea.session import HANDLERS, Session
    from tests.nmea_stream import NASTY

    rng = random.Random(3)
    sentences = []
    for log in sorted((shared_dir / "data" / "gpsd").glob("*.log")):
        sentences += NmeaFramer().feed(log.read_bytes())
    for talker, kind, fields in list(sentences):
        for _ in range(3):
            f = list(fields)
            for _ in range(rng.randint(1, 3)):
                f[rng.randrange(len(f))] = rng.choice(NASTY + ("A", "1", "3", "E"))
            sentences.append((talker, kind, tuple(f)))
    st = Session()
    seen = set()
    for talker, kind, fields in sentences:
        kind = "P" + kind if talker == "P" else kind
        if kind not in HANDLERS:
            continue
        mask, new = st.parse(talker, kind, fields)
        assert new.keys() <= GATE.keys() | SPECIAL, (kind, new)
        for key in new.keys() - SPECIAL:
            assert GATE[key] == 0 or mask & GATE[key], (kind, fields, key)
        seen |= new.keys()
        st.apply(mask, new)
    assert {"lat", "alt_msl", "speed", "track", "time_ns", "geoid_sep"} <= seen
