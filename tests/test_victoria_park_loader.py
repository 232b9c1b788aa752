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


def test_slam_service_on_the_first_minute(vp):
    """Messages of the first 90 s through LandmarkSlam: trees are mapped and the laser
    path stays within a few metres of the GPS (rigidly aligned)."""
    from mapping.slam import LandmarkSlam, SlamConfig

    slam = LandmarkSlam(SlamConfig(initial_sigma=(1e-3, 1e-3, 1e-3)))
    t_end = vp.dr_time_s[0] + 90.0
    events = [(m.stamp_ns, 0, m) for m in vp.controls() if m.stamp_ns < t_end * 1e9]
    events += [(m.stamp_ns, 1, m) for m in vp.landmark_scans() if m.stamp_ns < t_end * 1e9]
    track = []
    for stamp, kind, msg in sorted(events, key=lambda e: (e[0], e[1])):
        if kind == 0:
            est = slam.on_control(msg)
        else:
            est, lmap = slam.on_scan(msg)
        track.append((stamp * 1e-9, est.pose.x, est.pose.y))
    track = np.array(track)
    assert len(lmap.ids) > 10 and len(lmap.xs) == len(lmap.cov_xx)
    assert min(lmap.cov_xx) > 0
    sel = (vp.gps_time_s > track[0, 0] + 5) & (vp.gps_time_s < track[-1, 0])
    k = np.searchsorted(track[:, 0], vp.gps_time_s[sel]) - 1
    est = track[k, 1:]
    gps = np.stack([vp.gps_x_m[sel], vp.gps_y_m[sel]], 1)
    # best rigid alignment (Kabsch)
    mu_e, mu_g = est.mean(0), gps.mean(0)
    u, _, vt = np.linalg.svd((est - mu_e).T @ (gps - mu_g))
    r = vt.T @ np.diag([1.0, np.sign(np.linalg.det(vt.T @ u.T))]) @ u.T
    err = np.linalg.norm((est - mu_e) @ r.T + mu_g - gps, axis=1)
    assert np.ptp(gps[:, 0]) + np.ptp(gps[:, 1]) > 40  # the car did drive
    assert np.sqrt(np.mean(err**2)) < 3.0
