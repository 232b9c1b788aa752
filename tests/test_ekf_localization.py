"""Odometry model (eq. 1-2), its Jacobians against finite differences, the EKF (eq. 3-4)
and the EKF/CP integrity monitor."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numjac import numeric_jacobian

from fakes.world.paper_scenario import simulate
from localization.ekf import EkfConfig, EkfLocalizer, IntegrityMonitor
from localization.odometry import motion, motion_jacobians, wheels_from_poses
from msgs import GpsFix, GyroSample, Interval, Pose2D, PoseBox, PoseEstimate, RobotOdometry


@pytest.mark.parametrize("kappa,chord", [(0.5, True), (1.0, False), (0.5, False)])
def test_motion_jacobians_match_finite_differences(kappa, chord):
    rng = np.random.default_rng(21)
    e = 0.33
    for _ in range(50):
        s = rng.uniform([-10, -10, -4], [10, 10, 4])
        u = rng.uniform(-0.2, 0.2, 2)
        if rng.random() < 0.2:
            u[1] = u[0] + rng.uniform(-1e-6, 1e-6)  # the near-straight branch
        a, w = motion_jacobians(s, u, e, kappa, chord)
        na = numeric_jacobian(lambda v, u=u: motion(v, u, e, kappa, chord), s)
        nw = numeric_jacobian(lambda v, s=s: motion(s, v, e, kappa, chord), u)
        np.testing.assert_allclose(a, na, atol=1e-6)
        np.testing.assert_allclose(w, nw, atol=1e-6)


def test_wheels_from_poses_inverts_the_model():
    rng = np.random.default_rng(22)
    for _ in range(100):
        s = rng.uniform([-5, -5, -3], [5, 5, 3])
        u = rng.uniform(-0.15, 0.15, 2)
        s1 = motion(s, u, 0.33)
        r, l = wheels_from_poses(Pose2D(*s), Pose2D(s1[0], s1[1], s1[2]), 0.33)
        assert abs(r - u[0]) < 1e-9 and abs(l - u[1]) < 1e-9


def _run_ekf(sc, i):
    b = sc.bounds
    cfg = EkfConfig(
        wheelbase_m=sc.wheelbase_m,
        wheel_sigma_abs_m=b.wheel_abs_m / math.sqrt(3),
        wheel_sigma_rel=b.wheel_rel / math.sqrt(3),
        gps_sigma_m=b.gps_m / math.sqrt(3),
        gyro_sigma_rad=b.gyro_rad / math.sqrt(3),
    )
    tr = sc.truth[i]
    init = PoseEstimate(
        0,
        Pose2D(*sc.gps[i, 0], sc.gyro[i, 0]),
        tuple(np.diag([b.gps_m**2 / 3] * 2 + [b.gyro_rad**2 / 3]).ravel()),
    )
    ekf = EkfLocalizer(cfg, initial=init)
    errs = []
    for s in range(1, sc.steps):
        ekf.predict(sc.dsr[i, s], sc.dsl[i, s])
        ekf.update_heading(sc.gyro[i, s])
        ekf.update_gps(*sc.gps[i, s])
        errs.append(ekf.s - tr[s])
    return ekf, np.array(errs)


def test_ekf_tracks_the_truth_better_than_gps():
    sc = simulate(duration_s=20.0, seed=5)
    for i in range(3):
        ekf, errs = _run_ekf(sc, i)
        rms = np.sqrt(np.mean(errs[50:, :2] ** 2))
        gps_rms = np.sqrt(np.mean((sc.gps[i, 50:] - sc.truth[i, 50:, :2]) ** 2))
        assert rms < 0.3 * gps_rms
        # Consistent: normalised errors of the order of 1.
        sig = np.sqrt(np.diag(ekf.P))
        assert np.all(np.abs(errs[-1]) < 5 * sig)


def test_ekf_message_api_and_integrity_monitor():
    sc = simulate(duration_s=5.0, seed=6)
    ekf = EkfLocalizer(EkfConfig(wheelbase_m=sc.wheelbase_m))
    mon = IntegrityMonitor()
    i = 0
    pose = Pose2D()
    for s in range(sc.steps):
        if s:  # the odometry pose integrates the measured wheel travel
            p = motion(
                np.array([pose.x, pose.y, pose.theta]), (sc.dsr[i, s], sc.dsl[i, s]), sc.wheelbase_m
            )
            pose = Pose2D(p[0], p[1], p[2])
        st = int(sc.stamps_ns[s])
        odo = RobotOdometry(st, pose, 1.0, 1.0, 1.0, 0.0, 12.0, True, True)
        assert ekf.feed(odo) is not None
        ekf.feed(GyroSample(st, 0.0, float(sc.gyro[i, s])))
        est = ekf.feed(
            GpsFix(st, mode=3, east_m=float(sc.gps[i, s, 0]), north_m=float(sc.gps[i, s, 1]))
        )
        assert isinstance(est, PoseEstimate)
    assert ekf.feed(GpsFix(1, mode=1)) is None and ekf.skipped["gps_no_fix"] == 1
    est = ekf.estimate()
    tr = sc.truth[i, -1]
    assert math.hypot(est.pose.x - tr[0], est.pose.y - tr[1]) < 1.0
    box = ekf.box(3.0, robot="r1")
    assert box.x.contains(tr[0]) and box.y.contains(tr[1])
    # Integrity: inside a box around the estimate; outside a box beside it -> alarm + clip.
    rep = mon.check(est, box)
    assert rep.inside and rep.distance_m == 0.0
    far = PoseBox(est.stamp_ns, "r1", Interval(est.pose.x + 1, est.pose.x + 2), box.y, box.theta)
    rep = mon.check(est, far)
    assert not rep.inside and rep.clipped.x == est.pose.x + 1 and abs(rep.distance_m - 1.0) < 1e-9
    assert mon.alarms == [est.stamp_ns] and mon.alarm_rate == 0.5
