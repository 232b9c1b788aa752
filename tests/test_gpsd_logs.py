"""Every gpsd regression log in the shared folder, through the NMEA codec, agrees with gpsd.

The logs are ``data/gpsd/X.log`` with gpsd's output ``X.log.chk`` (found through
``tests/conftest.py``; ``HILNAV_SHARED`` points at another shared folder, e.g. one with
other receivers' logs). The comparison is :mod:`tests.gpsd_compare`: epochs matched by
time, TPV fields time, mode, lat, lon, altMSL, altHAE, speed, track, climb, eph and epv,
SKY nSat and uSat, each to the precision gpsd prints. Every field must agree on every
epoch (``HILNAV_GPSD_MIN_AGREEMENT``, a fraction, lowers that bar for logs the codec is
not yet pinned by); the agreement per log and field is printed and is part of the
assertion message.
"""

from __future__ import annotations

import os

from tests.gpsd_compare import Agreement, compare

MIN_AGREEMENT = float(os.environ.get("HILNAV_GPSD_MIN_AGREEMENT", "1.0"))


def test_every_gpsd_log_agrees_with_gpsd(shared_dir):
    folder = shared_dir / "data" / "gpsd"
    logs = sorted(folder.glob("*.log"))
    assert logs, f"no gpsd logs in {folder}"
    total = Agreement()
    lines = []
    for log in logs:
        chk = log.with_name(log.name + ".chk")
        assert chk.is_file(), f"{log.name} has no {chk.name}"
        agree = compare(log, chk)
        assert agree.counts.get("time", (0, 0))[1] > 0, f"{chk.name} has no timed TPV"
        lines.append(f"{log.stem}: {agree.table()}")
        total.merge(agree)
    lines.append(f"all {len(logs)} logs: {total.table()}")
    report = "\n".join(lines)
    print(report)
    low = {k: round(total.fraction(k), 4) for k in total.counts}
    low = {k: v for k, v in low.items() if v < MIN_AGREEMENT}
    assert not low, f"fields below {MIN_AGREEMENT:.0%}: {low}\n{report}\n" + "\n".join(total.misses)
    for name in ("time", "mode", "lat", "lon", "altMSL", "speed", "track", "eph"):
        assert total.counts.get(name, (0, 0))[1] > 0, f"no epoch compared {name}"
