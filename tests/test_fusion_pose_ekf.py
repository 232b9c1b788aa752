"""Pose EKF (ekf-vs-cp eq. 1-4): Jacobians, consistency, gating, ordering, reset, covariance."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from fusion import models
from fusion.ekf_update import is_pd
from fusion.pose_ekf import PoseEkf, PoseEkfParams
from msgs import GpsFix, GyroSample, Pose2D, RobotOdometry, wrap_angle

DEG = math.pi / 180.0
MS = 1_000_000


def odo(t_ms: int, x: float, y: float, th: float, moving: bool = True) -> RobotOdometry:
    return RobotOdometry(t_ms * MS, Pose2D(x, y, wrap_angle(th)), 0.0, 0.0, 0.0, 0.0, 12.0,
                         moving, True)  # fmt: skip


def fix(t_ms: int, e: float, n: float, std: float | None = 1.0, hdop: float | None = 1.0):
    return GpsFix(t_ms * MS, mode=3, quality=1, hdop=hdop, std_lat_m=std, std_lon_m=std,
                  east_m=e, north_m=n)  # fmt: skip


def numeric_jacobian(fn, x0: np.ndarray, eps: float = 1e-6) -> np.ndarray:
    cols = []
    for i in range(len(x0)):
        d = np.zeros_like(x0)
        d[i] = eps
        a, b = fn(x0 + d), fn(x0 - d)
        diff = a - b
        cols.append(diff / (2 * eps))
    return np.stack(cols, axis=1)


@pytest.mark.parametrize("c", [0.0, 0.5, 1.0])
def test_motion_jacobians_match_finite_differences(c):
    rng = np.random.default_rng(11)
    for _ in range(50):
        x = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-3.1, 3.1)])
        u = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.6, 0.6)])
        f, g = models.motion_jacobians(x, u, c)

        def fx(s, u=u):
            out = models.motion(s, u, c)
            out[2] = s[2] + u[1]  # compare unwrapped (wrap is piecewise identity)
            return out

        def fu(v, x=x):
            out = models.motion(x, v, c)
            out[2] = x[2] + v[1]
            return out

        np.testing.assert_allclose(f, numeric_jacobian(fx, x), atol=1e-7)
        np.testing.assert_allclose(g, numeric_jacobian(fu, u), atol=1e-7)


def test_wheel_and_measurement_jacobians_match_finite_differences():
    rng = np.random.default_rng(12)
    b = 0.33
    for _ in range(50):
        w = rng.uniform(-0.2, 0.2, size=2)
        np.testing.assert_allclose(
            models.wheels_jacobian(b),
            numeric_jacobian(lambda v: models.wheels_to_step(v[0], v[1], b), w),
            atol=1e-8,
        )
        np.testing.assert_allclose(models.step_to_wheels(*models.wheels_to_step(*w, b), b), w)
        x = np.array([rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-3.1, 3.1)])
        lever = (rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3))
        _, hj = models.position_measurement(x, lever)
        num = numeric_jacobian(lambda s, lv=lever: models.position_measurement(s, lv)[0], x)
        np.testing.assert_allclose(hj, num, atol=1e-7)
        _, hh = models.heading_measurement(x)
        np.testing.assert_allclose(
            hh, numeric_jacobian(lambda s: models.heading_measurement(s)[0], x), atol=1e-8
        )


def test_gps_bias_model_jacobians_match_finite_differences():
    rng = np.random.default_rng(13)
    p = PoseEkfParams(gps_bias_sigma_m=1.5, gps_bias_tau_s=60.0)
    for _ in range(30):
        x = np.concatenate([rng.uniform(-5, 5, 2), rng.uniform(-3.1, 3.1, 1), rng.normal(0, 2, 2)])
        lever = (rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3))
        _, hj = models.biased_position_measurement(x, lever)
        num = numeric_jacobian(lambda s, lv=lever: models.biased_position_measurement(s, lv)[0], x)
        np.testing.assert_allclose(hj, num, atol=1e-7)
        dt = rng.uniform(0.01, 2.0)
        _, a, q = models.gauss_markov(x[3:], dt, p.gps_bias_tau_s, p.gps_bias_sigma_m)
        num = numeric_jacobian(
            lambda b, d=dt: models.gauss_markov(b, d, p.gps_bias_tau_s, p.gps_bias_sigma_m)[0],
            x[3:],
        )
        np.testing.assert_allclose(a * np.eye(2), num, atol=1e-8)
        # stationary: a^2 sigma^2 + q = sigma^2
        assert a * a * p.gps_bias_sigma_m**2 + q == pytest.approx(p.gps_bias_sigma_m**2)
        # the EKF's augmented prediction: F of the 5-state propagation vs finite differences
        ekf = PoseEkf(p, initial=Pose2D())
        u = rng.uniform(-0.1, 0.1, size=2)

        def prop(s, u=u, d=dt, ekf=ekf):
            ekf.x = np.array(s, float)
            ekf.P = np.eye(5)
            ekf.predict(float(u[0]), float(u[1]), dt_s=d)
            return ekf.x.copy()

        fx = numeric_jacobian(prop, x)
        ekf.x, ekf.P = x.copy(), np.zeros((5, 5))
        ekf.predict(float(u[0]), float(u[1]), dt_s=dt)
        # with P = 0 the predicted P is G Q G^T + Qb; with P = I it adds F F^T
        ekf2 = PoseEkf(p, initial=Pose2D())
        ekf2.x, ekf2.P = x.copy(), np.eye(5)
        ekf2.predict(float(u[0]), float(u[1]), dt_s=dt)
        np.testing.assert_allclose(ekf2.P - ekf.P, fx @ fx.T, atol=1e-6)


def _simulate_consistency(runs: int, steps: int, seed: int, bias: bool = False):
    """Runs drawn from the EKF's own noise models; NEES of the pose per step and NIS per
    update. ``bias``: the GPS error is a Gauss-Markov bias (the filter's bias states'
    model, 1 m, tau 20 s) plus the white noise R; else white only (3-state filter)."""
    p = PoseEkfParams(
        gate_probability=None,
        wheel_noise_m_per_sqrt_m=0.01,
        gps_bias_states=bias,
        gps_bias_sigma_m=1.0,
        gps_bias_tau_s=20.0,
    )
    rng = np.random.default_rng(seed)
    nees = np.empty((runs, steps))
    nis_gps, nis_gyro = [], []
    r_gps = np.diag([0.3**2, 0.5**2])
    for m in range(runs):
        p0 = np.diag([p.initial_sigma_xy_m**2] * 2 + [p.initial_sigma_theta_rad**2])
        truth = rng.multivariate_normal(np.zeros(3), p0)
        b = rng.normal(0.0, p.gps_bias_sigma_m, size=2) if bias else np.zeros(2)
        ekf = PoseEkf(p, initial=Pose2D(0.0, 0.0, 0.0))
        row_gps, row_gyro = [], []
        for k in range(steps):
            # True wheel motion: forward 5 cm a step with a wandering turn rate.
            w = 0.3 * math.sin(0.05 * k + m)
            dl_t = 0.05 - 0.5 * p.wheelbase_m * w * 0.1
            dr_t = 0.05 + 0.5 * p.wheelbase_m * w * 0.1
            # Measured step = true step + noise of the model's own covariance Q_u.
            q = models.step_covariance(dl_t, dr_t, p.wheelbase_m, p.wheel_noise_m_per_sqrt_m,
                                       p.wheel_noise_floor_m, p.turn_noise_fraction)  # fmt: skip
            u_m = rng.multivariate_normal(models.wheels_to_step(dl_t, dr_t, p.wheelbase_m), q)
            dl, dr = models.step_to_wheels(u_m[0], u_m[1], p.wheelbase_m)
            u_t = models.wheels_to_step(dl_t, dr_t, p.wheelbase_m)
            truth = models.motion(truth, u_t, p.heading_point)
            rg = (0.02 * u_t[1]) ** 2 + 1e-6
            dg = u_t[1] + rng.normal(0.0, math.sqrt(rg))
            res = ekf.predict(dl, dr, dg, rg, dt_s=0.1)
            row_gyro.append(res.nis)
            if bias:
                b, _, qb = models.gauss_markov(b, 0.1, p.gps_bias_tau_s, p.gps_bias_sigma_m)
                b = b + rng.normal(0.0, math.sqrt(qb), size=2)
            if k % 10 == 9:
                z = truth[:2] + b + rng.multivariate_normal(np.zeros(2), r_gps)
                row_gps.append(ekf.update_position(z, r_gps).nis)
            e = ekf.x[:3] - truth
            e[2] = wrap_angle(e[2])
            nees[m, k] = e @ np.linalg.solve(ekf.P[:3, :3], e)
        nis_gps.append(row_gps)
        nis_gyro.append(row_gyro)
    return nees, np.array(nis_gps), np.array(nis_gyro)


@pytest.mark.parametrize("bias", [False, True], ids=["white_gps", "gauss_markov_gps_bias"])
def test_nees_and_nis_inside_95_chi_square_bands_over_seeded_runs(bias):
    runs, steps = 50, 200
    nees, nis_gps, nis_gyro = _simulate_consistency(runs, steps, seed=21, bias=bias)

    def check(samples: np.ndarray, dof: int) -> None:
        lo = chi2.ppf(0.025, runs * dof) / runs
        hi = chi2.ppf(0.975, runs * dof) / runs
        avg = samples.mean(axis=0)  # over the runs, per step / per update
        assert lo <= avg.mean() <= hi, (avg.mean(), lo, hi)
        assert np.mean((avg >= lo) & (avg <= hi)) >= 0.85

    check(nees, 3)
    check(nis_gps, 2)
    check(nis_gyro, 1)


def test_gating_rejects_an_outlier_and_counts_it():
    ekf = PoseEkf(PoseEkfParams(gps_bias_states=False), initial=Pose2D(0.0, 0.0, 0.0))
    ekf.feed(odo(0, 0, 0, 0))
    for i in range(1, 11):
        ekf.feed(odo(i * 100, 0.04 * i, 0, 0))
    before = ekf.x.copy(), ekf.P.copy()
    assert ekf.feed(fix(1000, 0.4 + 30.0, 0.0)) is None  # 30 m multipath jump
    np.testing.assert_array_equal(ekf.x, before[0])
    np.testing.assert_array_equal(ekf.P, before[1])
    assert ekf.last_nis["gps"] > chi2.ppf(0.99, 2)
    assert ekf.counters()["gps_rejected"] == 1
    assert ekf.feed(fix(1100, 0.4 + 0.5, 0.2)) is not None  # a sane fix is taken
    c = ekf.counters()
    assert c["gps_updates"] == 1 and c["gps_rejected"] == 1
    # Without gating the same outlier is taken and drags the estimate towards it.
    free = PoseEkf(PoseEkfParams(gate_probability=None, gps_bias_states=False), initial=Pose2D())
    free.set_pose(Pose2D(), covariance=np.diag([1.0, 1.0, 1e-4]))
    free.feed(odo(0, 0, 0, 0))
    free.feed(odo(100, 0.04, 0, 0))
    assert free.feed(fix(100, 30.0, 0.0)) is not None
    assert free.x[0] > 10.0 and free.counters()["gps_updates"] == 1


def test_encoder_turn_contradicted_by_the_gyro_is_gated_and_the_gyro_kept():
    ekf = PoseEkf(initial=Pose2D())
    res = ekf.predict(0.05, 0.05, dtheta_gyro=0.5, gyro_var=1e-6)
    assert res is not None and not res.accepted and res.nis > chi2.ppf(0.99, 1)
    assert ekf.counters()["odometry_heading_rejected"] == 1
    assert ekf.x[2] == pytest.approx(0.5)
    assert ekf.P[2, 2] == pytest.approx(1e-6 + ekf.params.initial_sigma_theta_rad**2)


def test_out_of_order_measurements_are_rejected_and_counted():
    ekf = PoseEkf(PoseEkfParams(gps_max_lag_s=0.25), initial=Pose2D())
    ekf.feed(odo(0, 0, 0, 0))
    ekf.feed(odo(1000, 0.4, 0, 0))
    assert ekf.feed(fix(500, 0.2, 0.0)) is None  # older than the filter time by 0.5 s
    assert ekf.feed(fix(900, 0.4, 0.0)) is not None  # 0.1 s lag: applied, R inflated
    assert ekf.feed(fix(900, 0.4, 0.0)) is None  # not newer than the previous fix
    assert ekf.feed(odo(800, 0.3, 0, 0)) is None  # odometry going back in time
    ekf.feed(GyroSample(1000 * MS, 0.0, 0.0))
    ekf.feed(GyroSample(990 * MS, 0.0, 0.0))
    c = ekf.counters()
    assert c["out_of_order_gps"] == 2
    assert c["out_of_order_odometry"] == 1 and c["out_of_order_gyro"] == 1
    assert c["gps_updates"] == 1


def test_gps_covariance_from_gst_else_hdop_and_no_fix_skipped():
    biased = PoseEkf(PoseEkfParams(gps_white_fraction=0.3), initial=Pose2D())
    _, r = biased.gps_measurement(fix(0, 1.0, 2.0, std=0.7))  # bias states: the white part
    np.testing.assert_allclose(r, np.diag([0.21**2, 0.21**2]))
    p = PoseEkfParams(gps_uere_m=4.0, gps_bias_states=False)
    ekf = PoseEkf(p, initial=Pose2D())
    z, r = ekf.gps_measurement(fix(0, 1.0, 2.0, std=0.7))
    np.testing.assert_allclose(r, np.diag([0.49, 0.49]))
    np.testing.assert_allclose(z, [1.0, 2.0])
    _, r = ekf.gps_measurement(fix(0, 1.0, 2.0, std=None, hdop=1.5))
    np.testing.assert_allclose(r, np.eye(2) * (1.5 * 4.0) ** 2 / 2)
    assert ekf.gps_measurement(fix(0, 1.0, 2.0, std=None, hdop=None)) is None
    assert ekf.gps_measurement(GpsFix(0, mode=1, hdop=99.0)) is None
    assert ekf.feed(GpsFix(0, mode=1, hdop=99.0)) is None
    assert ekf.counters()["gps_no_fix"] == 1


def test_timeouts_flag_stale_sensors_and_predict_only():
    ekf = PoseEkf(PoseEkfParams(gps_timeout_s=1.0, gyro_timeout_s=0.3), initial=Pose2D())
    ekf.feed(GyroSample(0, 0.0, 0.0))
    ekf.feed(odo(0, 0, 0, 0))
    ekf.feed(fix(0, 0.0, 0.0))
    ekf.feed(GyroSample(100 * MS, 0.0, 0.0))
    ekf.feed(odo(100, 0.04, 0, 0))
    assert not ekf.gps_stale and not ekf.gyro_stale
    for i in range(2, 21):  # only odometry from here: the filter keeps predicting
        assert ekf.feed(odo(i * 100, 0.04 * i, 0, 0)) is not None
    c = ekf.counters()
    assert ekf.gps_stale and ekf.gyro_stale
    assert c["gps_timeouts"] == 1 and c["gyro_timeouts"] == 1
    assert c["predictions"] == 20 and c["gyro_fused"] == 1
    assert ekf.x[0] == pytest.approx(0.8, abs=1e-9)
    assert ekf.stale(2000 * MS) == {"odometry": False, "gyro": True, "gps": True}
    assert ekf.stale(3000 * MS)["odometry"]


def test_reset_and_set_pose():
    ekf = PoseEkf(initial=Pose2D(1.0, 2.0, 0.0))
    ekf.feed(odo(0, 0, 0, 0))
    ekf.feed(odo(100, 0.5, 0, 0.1))
    ekf.set_pose(Pose2D(10.0, -3.0, 4.0), stamp_ns=100 * MS, covariance=np.eye(3) * 0.04)
    est = ekf.estimate()
    assert (est.pose.x, est.pose.y) == (10.0, -3.0)
    assert est.pose.theta == pytest.approx(wrap_angle(4.0))
    assert est.covariance[0] == 0.04 and est.covariance[1] == 0.0
    ekf.feed(odo(200, 0.6, 0, 0.1))  # odometry continues from its baseline after set_pose
    assert ekf.x[0] == pytest.approx(10.0 + 0.1 * math.cos(wrap_angle(4.0)), abs=1e-6)
    with pytest.raises(ValueError, match="covariance"):
        ekf.set_pose(Pose2D(), covariance=-np.eye(3))
    ekf.reset()
    assert ekf.pose == Pose2D(1.0, 2.0, 0.0)
    assert ekf.feed(odo(300, 5.0, 5.0, 1.0)).pose == Pose2D(1.0, 2.0, 0.0)  # new baseline
    assert ekf.counters()["resets"] == 1


@pytest.mark.parametrize("bias", [False, True])
def test_first_gps_fix_initialises_position_when_no_pose_was_given(bias):
    p = PoseEkfParams(gps_bias_states=bias)
    ekf = PoseEkf(p)
    ekf.feed(odo(0, 0, 0, 0))
    est = ekf.feed(fix(0, 1234.0, -567.0, std=2.0))
    assert (est.pose.x, est.pose.y) == (1234.0, -567.0)
    # with bias states: the white part (fraction of the claimed sigma) plus the bias prior
    want = (0.3 * 2.0) ** 2 + p.gps_bias_sigma_m**2 if bias else 4.0
    assert est.covariance[0] == pytest.approx(want)
    assert is_pd(ekf.P)
    assert ekf.counters()["gps_init"] == 1
    assert ekf.feed(fix(1000, 1235.0, -567.0, std=2.0)) is not None  # then ordinary updates


def test_covariance_stays_symmetric_positive_definite():
    rng = np.random.default_rng(5)
    ekf = PoseEkf(PoseEkfParams(gate_probability=None), initial=Pose2D())
    for k in range(2000):
        dl, dr = rng.uniform(-0.05, 0.1, size=2)
        ekf.predict(dl, dr, rng.normal(0, 0.01), 1e-10 if k % 3 else None)
        if k % 7 == 0:  # very precise and very loose fixes, some nearly singular
            s = 10.0 ** rng.uniform(-4, 2, size=2)
            ekf.update_position(ekf.x[:2] + rng.normal(0, 1e-3, 2), np.diag(s**2))
        if k % 11 == 0:
            ekf.update_heading(rng.uniform(-math.pi, math.pi), 10.0 ** rng.uniform(-8, 0))
        np.testing.assert_array_equal(ekf.P, ekf.P.T)
        assert np.linalg.eigvalsh(ekf.P).min() > 0.0
    c = ekf.counters()
    assert c["gps_updates"] > 250 and c["heading_updates"] > 150


def test_bounds_and_estimate_messages():
    ekf = PoseEkf(PoseEkfParams(robot="r7"), initial=Pose2D(1.0, 2.0, 0.3))
    ekf.set_pose(Pose2D(1.0, 2.0, 0.3), covariance=np.diag([0.01, 0.04, 0.0009]))
    box = ekf.bounds(3.0)
    assert box.robot == "r7" and box.frame == "map"
    assert (box.x.lo, box.x.hi) == pytest.approx((0.7, 1.3))
    assert (box.y.lo, box.y.hi) == pytest.approx((1.4, 2.6))
    assert (box.theta.lo, box.theta.hi) == pytest.approx((0.21, 0.39))
    est = ekf.estimate()
    assert est.frame == "map" and est.source == "pose_ekf" and len(est.covariance) == 9


def test_bad_input_counted_not_raised():
    ekf = PoseEkf(initial=Pose2D())
    assert ekf.predict(math.nan, 0.1) is None
    assert not ekf.update_position(np.array([math.nan, 0.0]), np.eye(2)).accepted
    assert ekf.feed(GpsFix(0, mode=3, quality=1, hdop=1.0, east_m=math.inf, north_m=0.0)) is None
    assert ekf.counters()["bad_input"] == 2
    with pytest.raises(TypeError):
        ekf.feed(object())
    with pytest.raises(ValueError, match="gate_probability"):
        PoseEkfParams(gate_probability=1.5)


def test_message_level_drive_with_gyro_and_gps_tracks_a_square():
    """Odometry overstating every turn by 5 %, an exact gyro and noisy GPS: a 4 x 4 m square."""
    rng = np.random.default_rng(8)
    ekf = PoseEkf(initial=Pose2D())
    enc_only = PoseEkf(initial=Pose2D())
    truth = np.zeros(3)
    odo_pose = np.zeros(3)
    g_angle = 0.0
    t = 0
    for _lap in range(2):
        for _side in range(4):
            for seg, (ds, dth) in ((40, (0.1, 0.0)), (20, (0.0, math.pi / 40))):
                for _ in range(seg):
                    t += 100
                    u = np.array([ds, dth])
                    truth = models.motion(truth, u)
                    odo_pose = models.motion(odo_pose, np.array([ds, 1.05 * dth]))
                    g_angle += dth
                    ekf.feed(GyroSample(t * MS, dth * 10, g_angle))
                    m = odo(t, *odo_pose)
                    ekf.feed(m)
                    enc_only.feed(m)
                    if t % 1000 == 0:
                        e, n = truth[:2] + rng.normal(0, 0.3, 2)
                        ekf.feed(fix(t, e, n, std=0.3))
    err = math.hypot(*(ekf.x[:2] - truth[:2]))
    err_enc = math.hypot(*(enc_only.x[:2] - truth[:2]))
    assert err < 0.3 and err_enc > 1.0
    assert abs(wrap_angle(ekf.x[2] - truth[2])) < 0.02


def test_gps_error_correlation_inflates_r_by_tau_over_gap():
    def run(tau: float) -> PoseEkf:
        ekf = PoseEkf(
            PoseEkfParams(gps_error_correlation_s=tau, gps_bias_states=False), initial=Pose2D()
        )
        ekf.set_pose(Pose2D(), covariance=np.diag([100.0, 100.0, 1e-4]))
        ekf.feed(odo(0, 0, 0, 0))
        ekf.feed(fix(0, 1.0, 1.0, std=1.0))  # first fix: R as claimed
        ekf.feed(odo(1000, 0.0, 0, 0))
        ekf.feed(fix(1000, 1.0, 1.0, std=1.0))  # 1 s later: R x tau / 1 s
        return ekf

    white, corr = run(0.0), run(10.0)
    p0 = 100.0 * 1.0 / 101.0  # after the first fix, identical in both
    assert white.P[0, 0] == pytest.approx(p0 * 1.0 / (p0 + 1.0), rel=1e-3)
    assert corr.P[0, 0] == pytest.approx(p0 * 10.0 / (p0 + 10.0), rel=1e-3)
    with pytest.raises(ValueError, match="gps_error_correlation_s"):
        PoseEkfParams(gps_error_correlation_s=-1.0)
