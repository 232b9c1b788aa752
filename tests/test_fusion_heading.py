"""Heading Kalman filter (ir-grid-mapping eq. 1-4): equations, message handling, consistency."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

from fakes.world import DiffDriveRobot, GyroErrorModel, SlipModel
from fusion.heading import HeadingFilter, HeadingParams
from msgs import GyroSample, Pose2D, RobotOdometry, wrap_angle

DEG = math.pi / 180.0
MS = 1_000_000


def odo(t_ms: int, x: float, y: float, th: float, moving: bool = True) -> RobotOdometry:
    return RobotOdometry(t_ms * MS, Pose2D(x, y, wrap_angle(th)), 0.0, 0.0, 0.0, 0.0, 12.0,
                         moving, True)  # fmt: skip


def gyro(t_ms: int, angle: float, rate: float = 0.0) -> GyroSample:
    return GyroSample(t_ms * MS, rate, angle, wrap_angle(angle))


def test_first_odometry_sets_baseline_without_motion():
    f = HeadingFilter(initial=Pose2D(1.0, 2.0, 0.5))
    est = f.feed(odo(100, 10.0, 20.0, -1.0))
    assert est is not None
    assert (est.pose.x, est.pose.y, est.theta_rad) == (1.0, 2.0, 0.5)
    assert est.variance_rad2 == pytest.approx((0.1 * DEG) ** 2)
    assert est.stamp_ns == 100 * MS


def test_one_step_matches_eq_1_to_4():
    p = HeadingParams()
    f = HeadingFilter(p)
    dd, de, dg = 0.5, 0.20, 0.18
    f.step(dd, de, dg, 0.1)
    # Per distance and per turn (independent of the step rate), not per step squared:
    sw2 = p.alpha_rad_per_m**2 * dd + p.beta**2 * de
    sg2 = p.gamma**2 * dg
    k = sw2 / (sw2 + sg2)
    u = de + k * (dg - de)
    assert f.theta == pytest.approx(u, abs=1e-12)
    assert f.variance == pytest.approx((0.1 * DEG) ** 2 + sw2 * (1 - k), rel=1e-9)
    assert f.x == pytest.approx(dd * math.cos(u / 2)) and f.y == pytest.approx(dd * math.sin(u / 2))
    # The literal reading of eq. (1)-(3): gain on the whole prior, variance collapses.
    g = HeadingFilter(HeadingParams(model="paper"))
    g.step(dd, de, dg, 0.1)
    prior = (0.1 * DEG) ** 2 + (p.alpha_rad_per_m * dd) ** 2 + (p.beta * de) ** 2
    sg2 = (p.gamma * dg) ** 2
    kp = prior / (prior + sg2)
    assert g.theta == pytest.approx(de + kp * (dg - de), abs=1e-12)
    assert g.variance == pytest.approx(prior * (1 - kp), rel=1e-9)
    assert g.variance < f.variance


def test_encoder_only_without_gyro_follows_odometry_heading():
    f = HeadingFilter()
    th = 0.0
    f.feed(odo(0, 0, 0, 0))
    for i in range(1, 50):
        th += 0.07
        est = f.feed(odo(i * 100, 0.0, 0.0, th))
    assert est.theta_rad == pytest.approx(wrap_angle(th), abs=1e-9)
    c = f.counters()
    assert c["steps_encoder_only"] == 49 and c["steps_fused"] == 0 and c["gyro_stale"]


def _drive(f: HeadingFilter, gyro_period_ms: int, n_odo: int, w_true: float, enc_scale: float):
    """Turn on the spot at w_true; encoder overstates by enc_scale; gyro exact. Returns truth."""
    t_gyro = 0
    f.feed(gyro(0, 0.0))
    f.feed(odo(0, 0, 0, 0))
    for i in range(1, n_odo + 1):
        t = i * 100
        while t_gyro + gyro_period_ms <= t:
            t_gyro += gyro_period_ms
            f.feed(gyro(t_gyro, w_true * t_gyro / 1000.0, w_true))
        f.feed(odo(t, 0.0, 0.0, enc_scale * w_true * t / 1000.0))
    return w_true * t_gyro / 1000.0


@pytest.mark.parametrize("period_ms", [10, 7, 33, 100])
def test_gyro_at_other_rates_is_accumulated_between_odometry(period_ms):
    p = HeadingParams()
    f = HeadingFilter(p)
    w, scale = 0.5, 1.05
    truth = _drive(f, period_ms, 40, w, enc_scale=scale)
    enc = scale * w * 4.0
    # Each step fuses the encoder's and the gyro's turn with the same gain (eq. 2 on the step):
    # the result is the K-weighted mean of the two totals, up to the part of the last
    # odometry interval the gyro had not reported yet (less than one gyro period).
    de, dg = scale * w * 0.1, w * 0.1
    sw2, sg2 = (p.beta * de) ** 2, (p.gamma * dg) ** 2
    k = sw2 / (sw2 + sg2)
    expected = k * w * 4.0 + (1 - k) * enc
    assert abs(wrap_angle(f.theta - expected)) <= w * period_ms / 1000.0 + 1e-6
    assert abs(wrap_angle(f.theta - truth)) < 0.1 * abs(enc - truth) + w * period_ms / 1000.0
    assert f.counters()["steps_fused"] == 40


def test_angle_wrap_through_pi_with_wrapped_only_gyro_angle():
    f = HeadingFilter(initial=Pose2D(0.0, 0.0, 3.0))
    f.feed(GyroSample(0, 0.0, 3.0, 3.0))
    f.feed(odo(0, 0, 0, 3.0))
    th = 3.0
    for i in range(1, 21):
        th += 0.05
        # The device's wrapped angle as angle_rad (no unwrapping upstream): deltas still fine.
        f.feed(GyroSample(i * 100 * MS, 0.5, wrap_angle(th), wrap_angle(th)))
        est = f.feed(odo(i * 100, 0.0, 0.0, th))
        assert -math.pi < est.theta_rad <= math.pi
    assert wrap_angle(est.theta_rad - th) == pytest.approx(0.0, abs=1e-9)
    assert est.theta_rad < 0.0  # passed +pi into the negative half
    assert f.counters()["gyro_discontinuities"] == 0


def test_gyro_reset_is_a_counted_discontinuity_not_a_jump():
    f = HeadingFilter()
    f.feed(gyro(0, 1.0))
    f.feed(odo(0, 0, 0, 0))
    f.feed(gyro(50, 1.0))
    f.feed(gyro(100, 0.0, rate=0.0))  # device re-zeroed its angle
    est = f.feed(odo(100, 0.01, 0.0, 0.0))
    assert abs(est.theta_rad) < 1e-6
    assert f.counters()["gyro_discontinuities"] == 1


def test_gyro_timeout_falls_back_to_encoder_and_is_counted():
    f = HeadingFilter(HeadingParams(gyro_timeout_s=0.3))
    f.feed(gyro(0, 0.0))
    f.feed(odo(0, 0, 0, 0))
    f.feed(gyro(100, 0.01))
    f.feed(odo(100, 0.01, 0, 0.01))
    assert not f.gyro_stale
    for i in range(2, 10):  # gyro silent from here on
        f.feed(odo(i * 100, 0.01 * i, 0, 0.01 * i))
    c = f.counters()
    assert f.gyro_stale and c["gyro_timeouts"] == 1
    assert c["steps_fused"] == 1 and c["steps_encoder_only"] == 8
    assert f.theta == pytest.approx(0.09, abs=1e-9)


def test_out_of_order_and_bad_messages_are_counted_not_raised():
    f = HeadingFilter()
    f.feed(odo(100, 0, 0, 0))
    assert f.feed(odo(50, 1, 0, 0)) is None
    f.feed(gyro(100, 0.0))
    f.feed(gyro(90, 0.0))
    assert f.feed(odo(200, 500.0, 0, 0)) is not None  # a jump: re-baselined, no motion
    assert f.x == 0.0
    f.step(math.nan, 0.0, None, 0.1)
    c = f.counters()
    assert c["odometry_out_of_order"] == 1 and c["gyro_out_of_order"] == 1
    assert c["odometry_jumps"] == 1 and c["bad_input"] == 1
    with pytest.raises(TypeError):
        f.feed("not a message")
    with pytest.raises(ValueError, match="alpha_rad_per_m"):
        HeadingParams(alpha_rad_per_m=-1.0)


def test_bias_is_learnt_at_rest_and_removed():
    bias = 0.2 * DEG
    f = HeadingFilter()
    for i in range(0, 51):  # 5 s at rest, gyro drifting by its bias at 100 Hz
        for j in range(10):
            t = i * 100 + j * 10
            f.feed(gyro(t, bias * t / 1000.0, bias))
        f.feed(odo(i * 100, 0.0, 0.0, 0.0, moving=False))
    assert f.gyro_bias_radps == pytest.approx(bias, rel=1e-3)
    assert abs(f.theta) < 1e-9  # at rest the (biased) gyro does not move the heading
    t0 = 5000
    for i in range(1, 101):  # drive straight 10 s: gyro shows only its bias
        for j in range(10):
            t = t0 + (i - 1) * 100 + (j + 1) * 10
            f.feed(gyro(t, bias * t / 1000.0, bias))
        f.feed(odo(t0 + i * 100, 0.04 * i, 0.0, 0.0))
    assert abs(f.theta) < 1e-4


def test_reset_restarts_at_the_given_pose():
    f = HeadingFilter()
    f.feed(odo(0, 0, 0, 0))
    f.feed(odo(100, 1.0, 0, 0.3))
    f.reset(Pose2D(5.0, 6.0, 1.0), stamp_ns=7)
    est = f.estimate()
    assert (est.pose.x, est.pose.y, est.theta_rad, est.stamp_ns) == (5.0, 6.0, 1.0, 7)
    assert f.feed(odo(200, 3.0, 0, 0.5)).pose.x == 5.0  # new baseline after a reset


SYSTEMATIC = HeadingParams(
    encoder_bias_sigma_rad_per_m=2 * DEG, track_scale_sigma=0.02, gyro_scale_sigma=0.005
)
# Little random error: the systematic terms dominate.
QUIET = replace(SYSTEMATIC, alpha_rad_per_m=0.5 * DEG, beta=0.02)


def _nees_runs(
    params: HeadingParams, runs: int, steps: int, seed: int, gyro: bool = True,
    truth_params: HeadingParams | None = None,
) -> np.ndarray:  # fmt: skip
    """NEES per (run, step) on heading runs drawn from the filter's own noise model
    (``truth_params``, default ``params``): random growth per distance and per turn, and
    systematic errors drawn once per run from their priors."""
    tp = truth_params or params
    rng = np.random.default_rng(seed)
    out = np.empty((runs, steps))
    for m in range(runs):
        f = HeadingFilter(params)
        truth = rng.normal(0.0, params.initial_sigma_rad)  # the filter starts at 0
        c_d = rng.normal(tp.encoder_bias_rad_per_m, tp.encoder_bias_sigma_rad_per_m)
        c_t = rng.normal(0.0, tp.track_scale_sigma)
        c_g = rng.normal(0.0, tp.gyro_scale_sigma)
        for k in range(steps):
            dd = rng.uniform(0.0, 0.05)
            dth = rng.normal(0.0, 0.05)
            sw = math.sqrt(tp.alpha_rad_per_m**2 * dd + tp.beta**2 * abs(dth))
            de = (dth - c_d * dd + rng.normal(0.0, sw)) / (1.0 + c_t)
            dg = dth * (1.0 + c_g) + rng.normal(0.0, tp.gamma * math.sqrt(abs(dth)))
            truth += dth
            f.step(dd, de, dg if gyro else None, 0.1)
            e = wrap_angle(f.theta - truth)
            out[m, k] = e * e / f.variance
    return out


@pytest.mark.parametrize("params", [HeadingParams(), SYSTEMATIC], ids=["random", "systematic"])
def test_heading_nees_inside_95_band_over_seeded_runs(params):
    runs, steps = 60, 150
    nees = _nees_runs(params, runs, steps, seed=3)
    lo, hi = chi2.ppf(0.025, runs) / runs, chi2.ppf(0.975, runs) / runs
    avg = nees.mean(axis=0)  # average over runs at each step
    assert lo <= avg.mean() <= hi
    assert np.mean((avg >= lo) & (avg <= hi)) >= 0.85
    # The literal eq. (1)-(4) is over-confident on the very same data: far out of band.
    paper = HeadingParams(model="paper")
    literal = _nees_runs(paper, runs, steps, seed=3, truth_params=params).mean(axis=0)
    assert literal.mean() > 10 * hi


def test_encoder_only_with_a_wheel_bias_stays_consistent_and_says_when_it_is_lost():
    runs, steps = 60, 400  # ~10 m each, no gyro: the systematic prior is all there is
    nees = _nees_runs(QUIET, runs, steps, seed=5, gyro=False).mean(axis=0)
    lo, hi = chi2.ppf(0.005, runs) / runs, chi2.ppf(0.995, runs) / runs
    assert lo <= nees[-1] <= hi and lo <= nees.mean() <= hi
    # Without the systematic terms the same runs are over-confident by far at the end.
    random_only = replace(QUIET, encoder_bias_sigma_rad_per_m=0.0, track_scale_sigma=0.0)
    naive = _nees_runs(random_only, runs, steps, seed=5, gyro=False, truth_params=QUIET)
    assert naive.mean(axis=0)[-1] > 3 * hi
    # 3 sigma grows with the distance: past 90 deg the filter says the heading is lost.
    f = HeadingFilter(SYSTEMATIC)
    while not f.lost:
        f.step(0.1, 0.0, None, 0.1)
    assert 3 * math.sqrt(f.variance) >= math.pi / 2 and f.counters()["heading_lost"]
    assert f.counters()["lost_steps"] == 1 and f.x > 10.0


@pytest.mark.parametrize("params", [HeadingParams(), SYSTEMATIC], ids=["random", "systematic"])
@pytest.mark.parametrize("gyro", [True, False], ids=["fused", "encoder"])
def test_heading_variance_does_not_depend_on_the_step_rate(params, gyro):
    """The same 20 m arc (0.5 rad/m) cut into 20, 200 and 2000 steps: the same variance."""
    finals = []
    for n in (20, 200, 2000):
        f = HeadingFilter(params)
        dd, dth = 20.0 / n, 10.0 / n
        for _ in range(n):
            f.step(dd, dth, dth if gyro else None, 40.0 / n)
        finals.append(f.variance)
    assert finals[0] > 10 * params.initial_sigma_rad**2
    assert finals == pytest.approx([finals[0]] * 3, rel=0.02)
    # The per-step reading of eq. (4) does depend on it: 100 times the steps, a 100th.
    paper = []
    for n in (20, 2000):
        f = HeadingFilter(HeadingParams(model="paper"))
        for _ in range(n):
            f.step(20.0 / n, 10.0 / n, None, 40.0 / n)
        paper.append(f.variance)
    assert paper[0] > 50 * paper[1]


def test_the_gyro_learns_the_wheel_bias():
    f = HeadingFilter(QUIET)
    rng = np.random.default_rng(2)
    bias = 3.0 * DEG  # rad per metre, the Intel robot's
    for _ in range(500):  # 25 m straight, with small wiggles
        dth = rng.normal(0.0, 0.02)
        f.step(0.05, dth - bias * 0.05, dth, 0.1)
    c_d = f.systematic["encoder_bias_rad_per_m"]  # the correction the encoders need
    assert c_d == pytest.approx(bias, rel=0.1)
    assert f.systematic["encoder_bias_sigma_rad_per_m"] < 0.3 * QUIET.encoder_bias_sigma_rad_per_m
    # Then, with the gyro gone, the learnt bias corrects the encoders.
    th0 = f.theta
    for _ in range(100):
        f.step(0.05, -bias * 0.05, None, 0.1)
    assert abs(wrap_angle(f.theta - th0)) < 0.2 * bias * 5.0


def test_fused_heading_beats_encoder_on_the_fakes_models():
    # The fakes' ground truth with a worn wheel (1 % radius error) turning in circles, the
    # fakes' CruzCore error model at 100 Hz; odometry at 10 Hz from the encoder ticks.
    robot = DiffDriveRobot("r", slip=SlipModel(radius_error=0.01), seed=4)
    gm = GyroErrorModel(seed=5, turn_on_bias_radps=0.0)
    enc = HeadingFilter()
    fused = HeadingFilter()
    dt, b, k = 0.01, robot.wheelbase_m, 1.0 / robot.ticks_per_m
    ang, th_odo, prev = 0.0, 0.0, (0, 0)
    for i in range(0, 3001):
        robot.command_wheels(0.4 - 0.1 * b, 0.4 + 0.1 * b)
        robot.step(dt)
        ang += gm.sample(robot.yaw_rate_radps, dt) * dt
        fused.feed(GyroSample(i * 10 * MS, 0.0, ang))
        if i % 10 == 0:
            lt, rt = robot.left_ticks, robot.right_ticks
            th_odo += ((rt - prev[1]) - (lt - prev[0])) * k / b
            prev = (lt, rt)
            m = odo(i * 10, 0.0, 0.0, th_odo)
            enc.feed(m)
            fused.feed(m)
    e_enc = abs(wrap_angle(enc.theta - robot.pose.theta))
    e_fused = abs(wrap_angle(fused.theta - robot.pose.theta))
    assert e_fused < e_enc / 3
    assert fused.variance > enc.params.initial_sigma_rad**2  # grows, never collapses


def test_gyro_delta_spanning_a_gap_is_fused_over_the_whole_deferred_interval():
    f = HeadingFilter(HeadingParams(gyro_timeout_s=0.5))
    f.feed(gyro(0, 0.0))
    f.feed(odo(0, 0, 0, 0))
    est = f.feed(odo(900, 0.3, 0, 0.0))  # gyro silent: encoder only, deferred
    assert est.theta_rad == 0.0 and f.gyro_stale
    f.feed(gyro(1000, 0.5))  # 0.5 rad over the whole second, not over the last 0.1 s
    est = f.feed(odo(1000, 0.34, 0, 0.0))
    c = f.counters()
    assert c["gyro_merges"] == 1 and c["steps_fused"] == 2 and c["steps_encoder_only"] == 0
    # 0.5 rad against the encoders' 0 is far beyond the gate: the encoders are the outlier
    assert c["odometry_heading_rejected"] == 1
    assert est.theta_rad == pytest.approx(0.5, rel=1e-9)


def test_gyro_silent_beyond_max_defer_is_given_up_and_counted():
    f = HeadingFilter(HeadingParams(gyro_timeout_s=0.5, gyro_max_defer_s=1.0))
    f.feed(gyro(0, 0.0))
    f.feed(odo(0, 0, 0, 0))
    for i in range(1, 13):
        f.feed(odo(i * 100, 0.03 * i, 0, 0.0))
    f.feed(gyro(1300, 0.5))  # chain broken: re-baselined here, not fused
    est = f.feed(odo(1300, 0.39, 0, 0.0))
    c = f.counters()
    assert c["gyro_misaligned"] == 1 and c["gyro_merges"] == 0 and c["steps_fused"] == 0
    assert est.theta_rad == 0.0
