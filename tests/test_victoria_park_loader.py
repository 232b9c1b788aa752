"""The Victoria Park loader on the real files, and its errors on missing ones."""

from __future__ import annotations

import functools
import shutil

import numpy as np
import pytest

import msgs
from mapping.slam.victoria_park import VictoriaParkError, load_victoria_park


@functools.cache
def _load(directory: str):
    return load_victoria_park(directory)


@pytest.fixture
def vp(shared_dir):
    d = shared_dir / "data" / "victoria_park"
    if not d.is_dir():
        pytest.skip("Victoria Park data absent")
    return _load(str(d))


def test_sizes_and_clocks(vp):
    assert len(vp.dr_time_s) == len(vp.speed_mps) == len(vp.steering_rad) == 61945
    assert np.allclose(np.diff(vp.dr_time_s), 0.025)
    assert len(vp.scans) == len(vp.scan_time_s) == 7249
    assert len(vp.gps_time_s) == len(vp.gps_x_m) == len(vp.gps_y_m) == 4466
    # one clock: every stream spans the same ~1549 s
    for t in (vp.dr_time_s, vp.scan_time_s, vp.gps_time_s):
        assert np.all(np.diff(t) > 0)
        assert 1540 < t[-1] - t[0] < 1555
    assert all(z.shape[0] == 3 for z in vp.scans)
    assert sum(z.shape[1] == 0 for z in vp.scans) > 0  # empty scans are kept, 3 x 0
    allz = np.hstack(vp.scans)
    assert vp.detections == allz.shape[1]
    assert allz[0].min() > 0 and allz[0].max() < 100  # ranges, m
    assert allz[1].min() >= 0 and allz[1].max() <= np.pi  # bearings 0..pi


def test_messages_round_trip(vp):
    scan = next(vp.landmark_scans())
    assert scan.bearing_zero == "y"
    assert len(scan.ranges_m) == len(scan.bearings_rad) == vp.scans[0].shape[1]
    assert msgs.decode(msgs.LandmarkScan, msgs.encode(scan)) == scan
    ctl = next(vp.controls())
    assert ctl.stamp_ns == round(vp.dr_time_s[0] * 1e9)
    assert msgs.decode(msgs.VehicleControl, msgs.encode(ctl)) == ctl
    fix = next(vp.gps_fixes())
    assert fix.east_m == vp.gps_x_m[0] and fix.north_m == vp.gps_y_m[0]


def test_missing_file_is_named(tmp_path, shared_dir):
    src = shared_dir / "data" / "victoria_park"
    if not src.is_dir():
        pytest.skip("Victoria Park data absent")
    for name in ("aa3_dr.mat", "VictoriaParkSinSincronizar.mat"):
        shutil.copy(src / name, tmp_path / name)
    with pytest.raises(VictoriaParkError, match="aa3_gpsx.mat"):
        load_victoria_park(tmp_path)
    with pytest.raises(VictoriaParkError, match="not found"):
        load_victoria_park(tmp_path / "nowhere")


def test_corrupt_file_is_reported(tmp_path):
    for name in ("aa3_dr.mat", "VictoriaParkSinSincronizar.mat", "aa3_gpsx.mat"):
        (tmp_path / name).write_bytes(b"not a mat file")
    with pytest.raises(VictoriaParkError, match="aa3_dr.mat"):
        load_victoria_park(tmp_path)
