"""Every gpsd regression log through the NMEA codec agrees with gpsd's TPV records.

Comparison (shared/protocols/sensors.md): TPVs without ``time`` (before the first RMC
date, or without a fix) are not comparable; several TPVs of one epoch -> the last one;
a gpsd time 1024 weeks after ours is the week-rollover correction and counts as equal.
"""

from __future__ import annotations

import datetime as dt
import json

import pytest

from drivers.nmea import ROLLOVER_S, NmeaCodec
from msgs import GpsFix

LOGS = ["bu353s4", "garmin25lp", "mt3339", "nmea-fuzzy-cases", "skytraq-fix"]


def _iso(t: str) -> dt.datetime:
    return dt.datetime.fromisoformat(t.replace("Z", "+00:00"))


def _expected(chk: str) -> dict[str, dict]:
    out: dict[str, dict] = {}
    for line in chk.splitlines():
        if line.startswith("{") and '"class":"TPV"' in line:
            tpv = json.loads(line)
            if "time" in tpv:
                out[tpv["time"]] = tpv  # several per epoch: the last wins
    return out


def test_every_log_is_covered(shared_dir):
    names = sorted(p.name[: -len(".log")] for p in (shared_dir / "data/gpsd").glob("*.log"))
    assert names == sorted(LOGS)


@pytest.mark.parametrize("name", LOGS)
def test_log_matches_gpsd(shared_dir, name):
    folder = shared_dir / "data/gpsd"
    raw = (folder / f"{name}.log").read_bytes()
    expected = _expected((folder / f"{name}.log.chk").read_text())
    assert expected, "the .chk file has timed TPVs"
    codec = NmeaCodec()
    fixes = []
    for i, line in enumerate(raw.splitlines(keepends=True)):
        if not line.startswith(b"#"):
            fixes += codec.feed(line, i)
    fixes += codec.flush()
    ours = {}
    for f in fixes:
        if isinstance(f, GpsFix) and f.time_utc:
            ours[_iso(f.time_utc)] = f
    assert codec.stats.bad_checksums == 0 and codec.malformed == 0
    compared = 0
    for t, tpv in expected.items():
        when = _iso(t)
        fix = ours.get(when) or ours.get(when - dt.timedelta(seconds=ROLLOVER_S))
        assert fix is not None, f"{name}: no fix for gpsd's epoch {t}"
        assert fix.mode == tpv["mode"], (t, fix)
        for key, ours_v, tol in (
            ("lat", fix.lat_deg, 1e-8),
            ("lon", fix.lon_deg, 1e-8),
            ("altMSL", fix.alt_msl_m, 1e-3),
        ):
            if key in tpv:
                assert ours_v is not None and abs(ours_v - tpv[key]) <= tol, (t, key, ours_v)
            else:
                assert ours_v is None, (t, key, ours_v)
        compared += 1
    assert compared == len(expected)
