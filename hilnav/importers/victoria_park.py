"""``hilnav import victoria-park``: the Victoria Park data set as a hilnav MCAP log.

Uses the Victoria Park loader (``mapping.slam.victoria_park.load_victoria_park``) and its
messages (``msgs.landmarks``). The three streams are merged in time order and logged for
the robot ``vp`` (``--robot``) with log time = message stamp (the data set's clock, ns):

| topic | message | rate |
|---|---|---|
| ``/vp/control`` | msgs.VehicleControl (encoder speed at the rear left wheel, steering) | 40 Hz |
| ``/vp/landmark_scan`` | msgs.LandmarkScan (tree range, bearing 0..pi with pi/2 ahead, diameter) | ~4.7 Hz |
| ``/vp/gps`` | msgs.GpsFix (east_m/north_m only, local metres) | ~3 Hz, gaps |

The "hilnav" metadata names the data set and the vehicle geometry from its notes
(L = 2.83 m wheel base, H = 0.76 m encoder offset, laser a = 0.95 m, b = 0.5 m). No
ground truth exists: ``hilnav analyze`` uses the GPS fixes as the reference.
"""

from __future__ import annotations

import heapq
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from hilnav.importers.report import ImportReport
from hilnav.log.writer import LogWriter

CONTROL_TOPIC = "control"
SCAN_TOPIC = "landmark_scan"
GPS_TOPIC = "gps"
GEOMETRY = {
    "wheel_base_m": "2.83",
    "encoder_offset_h_m": "0.76",
    "laser_a_m": "0.95",
    "laser_b_m": "0.5",
}


def _stream(topic: str, order: int, items: Iterator[Any]) -> Iterator[tuple[int, int, str, Any]]:
    for m in items:
        yield (m.stamp_ns, order, topic, m)


def import_victoria_park(
    directory: str | Path,
    out: str | Path,
    robot: str = "vp",
    duration_s: float | None = None,
    compression: str = "zstd",
) -> ImportReport:
    """Write the data set (or its first ``duration_s`` seconds) to the MCAP log ``out``."""
    from mapping.slam.victoria_park import load_victoria_park

    data = load_victoria_park(directory)  # VictoriaParkError (a ValueError) names the problem
    rep = ImportReport(str(directory), str(out), robot)
    merged = heapq.merge(
        _stream(CONTROL_TOPIC, 0, data.controls()),
        _stream(GPS_TOPIC, 1, data.gps_fixes()),
        _stream(SCAN_TOPIC, 2, data.landmark_scans()),
    )
    meta = {
        "robot": robot,
        "dataset": "victoria_park",
        "source": Path(directory).name,
        "plan": "",
        "reference": "gps",
        **GEOMETRY,
    }
    end_ns: int | None = None
    first = True
    with LogWriter(out, compression=compression, metadata=meta, wall_clock=False) as w:
        for stamp, _, topic, msg in merged:
            if first:
                first = False
                end_ns = stamp + int(duration_s * 1e9) if duration_s is not None else None
                rep.first_ns = stamp
            if end_ns is not None and stamp > end_ns:
                break
            w.write(f"/{robot}/{topic}", msg, stamp)
            rep.counts[topic] += 1
            rep.last_ns = stamp
            if topic == SCAN_TOPIC:
                rep.detections += len(msg.ranges_m)
    return rep
