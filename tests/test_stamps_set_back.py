"""A clock set back in a stream of stamped messages (msgs.stamps): more than a second
older than the last is followed as a new start by every filter, not skipped with
everything after it. Late messages within a second are still counted and skipped."""

from __future__ import annotations

import dataclasses
import math

import pytest

from fusion.arrival import ArrivalOrder
from fusion.increments import GyroDeltas, OdometryDeltas
from fusion.pose_ekf import PoseEkf, PoseEkfParams
from hilnav.config import load_config
from hilnav.pipeline import Pipeline
from msgs import GpsFix, GyroSample, Pose2D, RobotOdometry
from msgs.stamps import SET_BACK_NS, set_back
from tests.test_pipeline import drive

MS = 1_000_000


def odo(t_ms: int, x: float) -> RobotOdometry:
    return RobotOdometry(t_ms * MS, Pose2D(x, 0.0, 0.0), 0.2, 0.2, 0.2, 0.0, 12.0, True, True)


def test_the_rule() -> None:
    assert SET_BACK_NS == 1_000_000_000
    assert set_back(0, 1_000_000_001) and not set_back(0, 1_000_000_000)
    assert not set_back(5, 4)  # newer is never set back


def test_increments_start_again_after_a_clock_set_back() -> None:
    d = OdometryDeltas()
    d.feed(odo(10_000, 0.0))
    assert d.feed(odo(10_100, 0.02)).ds_m == pytest.approx(0.02)
    assert d.feed(odo(10_050, 0.03)) is None and d.out_of_order == 1  # late: skipped
    assert d.feed(odo(5_000, 0.04)) is None and d.jumps == 0  # set back: held
    assert d.feed(odo(10_200, 0.04)) is not None  # the old line goes on: it was a stray
    assert d.feed(odo(5_100, 0.05)) is None and d.jumps == 0  # held again
    assert d.feed(odo(5_200, 0.06)) is None and d.jumps == 1 and d.baselined  # confirmed
    step = d.feed(odo(5_300, 0.08))
    assert step is not None and step.ds_m == pytest.approx(0.02) and step.dt_s == pytest.approx(0.1)
    g = GyroDeltas()
    g.feed(GyroSample(10_000 * MS, 0.1, 1.0))
    g.feed(GyroSample(9_990 * MS, 0.1, 1.0))  # late: skipped
    g.feed(GyroSample(5_000 * MS, 0.1, 2.0))  # set back: held
    g.feed(GyroSample(5_010 * MS, 0.1, 2.001))  # confirmed: a new baseline, no change
    g.feed(GyroSample(5_020 * MS, 0.1, 2.003))
    assert (g.out_of_order, g.discontinuities) == (2, 1)
    delta = g.take()
    assert delta.angle_rad == pytest.approx(0.002) and delta.covered_s == pytest.approx(0.01)


def test_arrival_order_follows_odometry_set_back() -> None:
    a = ArrivalOrder(100.0)
    assert [o.stamp_ns for o in a.odometry(odo(10_000, 0.0))] == [10_000 * MS]
    assert a.odometry(odo(9_900, 0.0)) == [] and a.dropped == 1  # late: dropped
    assert a.odometry(odo(5_000, 0.0)) == [] and a.dropped == 2  # set back: held
    assert [o.stamp_ns for o in a.odometry(odo(5_100, 0.0))] == [5_100 * MS]  # confirmed
    assert [o.stamp_ns for o in a.odometry(odo(5_200, 0.0))] == [5_200 * MS]


def test_gps_after_a_clock_set_back_is_used() -> None:
    ekf = PoseEkf(PoseEkfParams(), initial=Pose2D())
    fix = lambda t, e: GpsFix(t * MS, mode=3, quality=1, hdop=1.0, std_lat_m=1.0,  # noqa: E731
                              std_lon_m=1.0, east_m=e, north_m=0.0)  # fmt: skip
    ekf.feed(odo(10_000, 0.0))
    ekf.feed(odo(10_100, 0.02))
    assert ekf.feed(fix(10_100, 0.02)) is not None
    ekf.feed(odo(5_000, 0.04))  # the clock set back: held
    ekf.feed(odo(5_100, 0.06))  # confirmed: the odometry follows
    assert ekf.feed(fix(5_100, 0.06)) is not None  # and so does the GPS
    assert ekf.counters()["out_of_order_gps"] == 0


@pytest.mark.parametrize("back_s", [10, 3600])
def test_a_log_whose_clock_was_set_back_replays_as_without_it(back_s: int) -> None:
    """A stream (a replayed log) whose stamps go back 10 s or 1 h mid-run: the heading
    ends within a degree of the run without the step and the pose within a step, and the
    pose box and the map are still published after the step (before, the heading froze
    or ended 139 deg off, and the throttled outputs stopped)."""
    inputs, _ = drive(seconds=30.0)
    k0 = 1200  # about 12 s in
    stepped = [(t, dataclasses.replace(m, stamp_ns=m.stamp_ns - back_s * 10**9) if k > k0 else m)
               for k, (t, m) in enumerate(inputs)]  # fmt: skip
    cfg = load_config(None)
    outs = {}
    for name, seq in (("clean", inputs), ("stepped", stepped)):
        p = Pipeline(cfg)
        outs[name] = [(k, o) for k, (t, m) in enumerate(seq) for o in p.feed(t, m)]
        p.close()
    last = {n: {t: m for _, (t, m) in o} for n, o in outs.items()}
    h0, h1 = last["clean"]["heading"], last["stepped"]["heading"]
    assert abs(math.remainder(h0.theta_rad - h1.theta_rad, 2 * math.pi)) < math.radians(1.0)
    assert h1.stamp_ns == h0.stamp_ns - back_s * 10**9  # it went on to the end
    p0, p1 = last["clean"]["pose"].pose, last["stepped"]["pose"].pose
    # the odometry steps across the set back until it is confirmed are not taken: at
    # most three steps, 12 cm at 0.4 m/s
    assert math.hypot(p0.x - p1.x, p0.y - p1.y) < 0.15
    # CP's box stays as wide as without the step (its gyro bound counts the time since
    # the gyro's first sample, which goes on across the step)
    b0, b1 = last["clean"]["pose_box"], last["stepped"]["pose_box"]
    area = [(b.x.hi - b.x.lo) * (b.y.hi - b.y.lo) for b in (b0, b1)]
    assert area[1] == pytest.approx(area[0], rel=0.1)
    assert b1.theta.hi - b1.theta.lo == pytest.approx(b0.theta.hi - b0.theta.lo, rel=0.1)
    after = {t for k, (t, _) in outs["stepped"] if k > k0 + 500}
    assert {"pose_box", "map", "heading", "pose"} <= after


def test_the_localizers_odometry_follows_a_clock_set_back() -> None:
    """The EKF and CP localizers (localization.ekf, localization.cp): odometry stamped
    more than a second before the last is a new baseline, counted; later steps move."""
    from localization.cp import CPConfig, CPLocalizer
    from localization.ekf import EkfConfig, EkfLocalizer

    ekf = EkfLocalizer(EkfConfig())
    cp = CPLocalizer(CPConfig())
    seq = ((10_000, 0.0), (10_100, 0.02), (9_950, 0.03), (5_000, 2.0), (10_200, 0.04),
           (5_100, 0.05), (5_200, 0.06), (5_300, 0.08))  # fmt: skip
    for t, x in seq:  # late; a stray 1 s back (2 m off); a set back (held, confirmed)
        ekf.feed(odo(t, x))
        cp.take_odometry(odo(t, x))
    assert ekf.skipped["odometry_out_of_order"] == 3  # late, stray, first of the step
    assert ekf.skipped["odometry_clock_set_back"] == 1
    assert ekf.estimate().pose.x == pytest.approx(0.06, abs=1e-9)  # 3 steps of 2 cm
    assert cp.skipped["odometry_clock_set_back"] == 1 and cp.stamp_ns == 5_300 * MS


def test_a_clock_set_forward_at_rest_leaves_the_bias_and_cp_heading_alone() -> None:
    """Stamps 1 h forward while the robot stands still (NTP setting a booting computer's
    clock): the gyro bias learnt at rest is not re-learnt from the angle over the whole
    hour (before: -0.17 rad/s, the heading 178 deg off), and CP's gyro drift bound grows
    by at most GYRO_GAP_S (before: by the hour, a heading box of 187 deg)."""
    from fusion.heading import HeadingFilter
    from localization.cp import GYRO_GAP_S, CPConfig, CPLocalizer

    f = HeadingFilter(arrival=ArrivalOrder(100.0))
    angle, bias = 0.0, 0.002
    for i in range(5000):  # 50 s at rest at 100 Hz, the stamps 1 h forward at 30 s
        t = 10**12 + i * 10 * MS + (3600 * 10**9 if i >= 3000 else 0)
        angle += bias * 0.01
        f.feed(GyroSample(t, bias, angle))
        if i % 10 == 5:
            f.feed(RobotOdometry(t, Pose2D(), 0, 0, 0, 0, 12, False, True))
    assert f._align.bias.bias_radps == pytest.approx(bias, rel=1e-3)
    assert abs(f.estimate().theta_rad) < math.radians(0.5)
    cfg = CPConfig()
    widths = []
    for jump in (0, 3600 * 10**9):
        cp = CPLocalizer(cfg)
        cp.take_odometry(odo(0, 0.0))
        for k in range(100):  # 10 s of gyro at 10 Hz, 1 h forward half-way
            t = k * 100 * MS + (jump if k >= 50 else 0)
            cp.take_odometry(odo(t // MS, 0.0))
            cp.take_gyro(t, 0.0)
        widths.append(cp.box().theta.hi - cp.box().theta.lo)
    assert widths[1] - widths[0] <= 2 * cfg.gyro_drift_bound_radps * GYRO_GAP_S + 1e-9


def test_a_gyro_silent_since_before_a_set_back_is_silent() -> None:
    """The odometry goes on after a clock set back and the gyro stops at the step: its
    last sample, from before the step, is not taken as fresh (the steps are the encoders'
    alone, the turn followed), and the pose EKF calls the GPS from before it stale."""
    from fusion.heading import HeadingFilter

    f = HeadingFilter(arrival=ArrivalOrder(100.0))
    ekf = PoseEkf(PoseEkfParams(), initial=Pose2D())
    th = 0.0
    for i in range(500):  # 5 s, gyro at 100 Hz, odometry at 10 Hz, a GPS fix
        t = 10**12 + i * 10 * MS
        f.feed(GyroSample(t, 0.0, 0.0))
        ekf.feed(GyroSample(t, 0.0, 0.0))
        if i % 10 == 5:
            o = RobotOdometry(t, Pose2D(), 0, 0, 0, 0, 12, False, True)
            f.feed(o)
            ekf.feed(o)
    ekf.feed(GpsFix(10**12 + 4_990 * MS, mode=3, quality=1, hdop=1.0, std_lat_m=1.0,
                    std_lon_m=1.0, east_m=0.0, north_m=0.0))  # fmt: skip
    for k in range(30):  # 3 s of odometry 10 s earlier, turning 0.01 rad a step; no gyro
        t = 10**12 - 5 * 10**9 + k * 100 * MS
        th += 0.01
        o = RobotOdometry(t, Pose2D(0.0, 0.0, th), 0, 0, 0, 0.1, 12, True, True)
        f.feed(o)
        ekf.feed(o)
    assert f.estimate().theta_rad == pytest.approx(th - 0.02, abs=0.015)  # minus 2 steps
    assert f.counters()["steps_encoder_only"] >= 20
    assert ekf.gps_stale
