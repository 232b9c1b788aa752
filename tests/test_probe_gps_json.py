"""``hilnav probe gps PORT --json``: gpsd's TPV/SKY/GST objects, one per line; the sky topic."""

from __future__ import annotations

import json
import subprocess

from drivers.nmea.gpsd_json import gpsd_objects, sky, tpv
from hilnav.devices import DEVICES
from hilnav.topics import DEVICE_TOPICS, PUBLISHED
from msgs import GpsFix, GpsSatellite, GpsSky
from tests.conftest import HILNAV, hilnav_env


def test_tpv_and_sky_use_gpsds_names_units_and_decimals():
    fix = GpsFix(1, time_utc="2026-11-23T09:00:00.000Z", lat_deg=37.123456789012,
                 lon_deg=-1.5, alt_msl_m=12.34567, alt_hae_m=30.0, mode=3, status=2,
                 eph_m=4.12345, climb_mps=-0.0001, dgps_age_s=3.0, dgps_station=12,
                 gst_rms_m=1.3, std_lat_m=0.3)  # fmt: skip
    obj = tpv(fix)
    assert obj == {
        "class": "TPV", "status": 2, "mode": 3, "time": "2026-11-23T09:00:00.000Z",
        "lat": 37.123456789, "lon": -1.5, "altHAE": 30.0, "altMSL": 12.3457, "alt": 12.3457,
        "climb": 0.0, "eph": 4.123, "dgpsAge": 3.0, "dgpsSta": 12,
    }  # fmt: skip
    assert [o["class"] for o in gpsd_objects(fix)] == ["TPV", "GST"]
    s = GpsSky(1, satellites=(GpsSatellite(65, 6, 1, 45.0, 120.0, None, True),), n_sat=1,
               u_sat=1, hdop=1.234)  # fmt: skip
    assert sky(s) == {
        "class": "SKY", "hdop": 1.23, "nSat": 1, "uSat": 1,
        "satellites": [{"PRN": 65, "el": 45.0, "az": 120.0, "used": True, "gnssid": 6,
                        "svid": 1}],
    }  # fmt: skip


def test_the_sky_is_a_published_device_topic_of_the_gps():
    assert DEVICE_TOPICS[GpsSky] == "sky" and "sky" in PUBLISHED
    assert GpsSky in DEVICES["gps"].messages


def test_probe_gps_json_prints_gpsd_objects(shared_dir):
    log = shared_dir / "data/gpsd/bu353s4.log"
    res = subprocess.run(
        [*HILNAV, "probe", "gps", str(log), "--json", "--seconds", "20"],
        capture_output=True, text=True, env=hilnav_env(), timeout=60,
    )  # fmt: skip
    assert res.returncode == 0, res.stderr
    objs = [json.loads(line) for line in res.stdout.splitlines()]
    tpvs = [o for o in objs if o["class"] == "TPV"]
    skies = [o for o in objs if o["class"] == "SKY"]
    assert len(tpvs) == 25 and tpvs[0]["time"] == "2014-12-31T03:07:19.000Z"
    assert tpvs[0]["lat"] == -37.784788333 and tpvs[0]["altMSL"] == 59.9
    assert tpvs[0]["eph"] == 20.9 and tpvs[1]["climb"] == -0.1
    assert any(o.get("nSat") == 12 and len(o["satellites"]) == 12 for o in skies)
