"""The gyro/odometry alignment front end (fusion.alignment, fusion.arrival), rule by rule,
and regression: late, bunched, stale or jumping messages never leave a heading offset.

The regression reproduces the demo glitch (demo-glitch.mcap, t = 68 s) with a synthetic
message sequence: the robot turns at 1 rad/s; the host stalls 0.5 s, then delivers five
SIPs all stamped with the late read time, then 48 gyro packets all stamped with it too
(arrival order as in the log). Filters that fused the step ending at the burst with the
few gyro samples read before the stall (a fraction of the rotation), then dropped the
burst's rotation as misaligned, kept a permanent -25 deg offset.
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from fusion.alignment import Deferred, GyroOdometryAlignment
from fusion.arrival import ArrivalOrder
from fusion.heading import HeadingFilter, HeadingParams
from fusion.increments import OdometryStep
from fusion.pose_ekf import PoseEkf
from msgs import GyroSample, Pose2D, RobotOdometry, wrap_angle

MS = 1_000_000
RATE = 1.0  # rad/s


def odo(t_ms: float, stamp_ms: float | None = None, dtheta: float = 0.0) -> RobotOdometry:
    """The odometry of time t_ms (pose on an arc), stamped stamp_ms."""
    t = t_ms / 1000.0
    th = RATE * t + dtheta
    pose = Pose2D(0.2 * math.sin(th), 0.2 * (1.0 - math.cos(th)), wrap_angle(th))
    st = int(round((t_ms if stamp_ms is None else stamp_ms) * MS))
    return RobotOdometry(st, pose, 0.1, 0.3, 0.2, RATE, 12.5, True, True)


def gyro(t_ms: float, stamp_ms: float | None = None) -> GyroSample:
    a = RATE * t_ms / 1000.0
    st = int(round((t_ms if stamp_ms is None else stamp_ms) * MS))
    return GyroSample(st, RATE, a, wrap_angle(a))


def stream(stall_ms: tuple[int, int] | None, gyro_first: bool = False) -> list[object]:
    """Gyro at 100 Hz, odometry at 10 Hz over 0-3 s; during the stall nothing arrives,
    at its end the SIPs and gyro packets of the stall come in bursts stamped with its end."""
    out: list[object] = []
    late_odo: list[object] = []
    late_gyro: list[object] = []
    for t in range(0, 3001, 10):
        stalled = stall_ms is not None and stall_ms[0] < t <= stall_ms[1]
        g = gyro(t, stall_ms[1] if stalled else None)
        (late_gyro if stalled else out).append(g)
        if t % 100 == 0:
            o = odo(t, stall_ms[1] + 1 if stalled else None)
            (late_odo if stalled else out).append(o)
        if stall_ms is not None and t == stall_ms[1]:
            out += late_gyro + late_odo if gyro_first else late_odo + late_gyro
    return out


def final_error(f: HeadingFilter | PoseEkf, msgs: list[object]) -> float:
    for m in msgs:
        f.feed(m)
    theta = f.theta if isinstance(f, HeadingFilter) else float(f.x[2])
    return abs(wrap_angle(theta - RATE * 3.0))


@pytest.mark.parametrize("make", [HeadingFilter, PoseEkf], ids=["heading", "pose_ekf"])
@pytest.mark.parametrize("gyro_first", [False, True], ids=["odometry_first", "gyro_first"])
def test_burst_of_late_messages_leaves_no_heading_offset(make, gyro_first):
    f = make(initial=Pose2D())
    clean = final_error(make(initial=Pose2D()), stream(None))
    err = final_error(f, stream((1600, 2100), gyro_first))
    assert err < clean + math.radians(0.5)
    c = f.counters()
    assert c["gyro_misaligned"] == 0


@pytest.mark.parametrize("make", [HeadingFilter, PoseEkf], ids=["heading", "pose_ekf"])
def test_stale_or_duplicated_sip_leaves_no_heading_offset(make):
    msgs = stream(None)
    i = next(
        k for k, m in enumerate(msgs) if isinstance(m, RobotOdometry) and m.stamp_ns > 1500 * MS
    )
    stale = odo(1200, 1505)  # an old SIP re-sent with a new stamp
    dup = msgs[i]  # the same SIP twice
    msgs = msgs[:i] + [stale] + msgs[i : i + 1] + [dup] + msgs[i + 1 :]
    f = make(initial=Pose2D())
    assert final_error(f, msgs) < math.radians(0.5)


@pytest.mark.parametrize("make", [HeadingFilter, PoseEkf], ids=["heading", "pose_ekf"])
@pytest.mark.parametrize("jump_deg", [25.0, 170.0])
def test_odometry_heading_jump_the_gyro_contradicts_leaves_no_offset(make, jump_deg):
    # From 1.5 s on the firmware's heading is off by jump_deg (a bad SIP, a re-zeroed
    # odometry heading): a jump within the plausible rate, or beyond it (re-baseline).
    jump = math.radians(jump_deg)
    msgs = [
        odo(m.stamp_ns / MS, dtheta=jump)
        if isinstance(m, RobotOdometry) and m.stamp_ns >= 1500 * MS
        else m
        for m in stream(None)
    ]
    f = make(initial=Pose2D())
    assert final_error(f, msgs) < math.radians(0.5)


# -- the front end, rule by rule (a recording filter: what is it asked to do?) -----------


class Recorder:
    """A fusion.alignment.AlignedFilter that records the calls of the front end."""

    heading_gate = 6.63  # chi-square 0.99, 1 dof

    def __init__(self) -> None:
        self.calls: list[tuple] = []

    def encoder_variance(self, step: OdometryStep) -> float:
        return (0.1 * step.dtheta_rad) ** 2 + 1e-8

    def gyro_variance(self, dtheta_rad: float, dt_s: float) -> float:
        return (0.02 * dtheta_rad) ** 2 + 1e-8

    def position(self) -> tuple[float, float]:
        return 0.0, 0.0

    def predict_step(self, step: OdometryStep, dtheta_gyro: float | None, covered_s: float) -> None:
        self.calls.append(("predict", step.t1_ns // MS, dtheta_gyro))

    def correct_deferred(self, d: Deferred, dtheta_gyro: float, covered_s: float) -> None:
        self.calls.append(("correct", d.t0_ns // MS, d.steps, dtheta_gyro))

    def turn(self, dtheta_gyro: float, covered_s: float) -> None:
        self.calls.append(("turn", dtheta_gyro))


def front(arrival: bool = True) -> tuple[GyroOdometryAlignment, Recorder]:
    params = HeadingParams(learn_bias_at_rest=False)
    return GyroOdometryAlignment(params, ArrivalOrder(100.0) if arrival else None), Recorder()


def feed(a: GyroOdometryAlignment, rec: Recorder, msgs: list[object]) -> list[int]:
    """Feed in arrival order; the stamps (ms) of the odometry the filter took."""
    taken = []
    for m in msgs:
        if isinstance(m, GyroSample):
            adv = a.feed_gyro(m, rec)
        else:
            assert isinstance(m, RobotOdometry)
            adv = a.feed_odometry(m, rec)
        if adv is not None:
            taken.append(adv.stamp_ns // MS)
    return taken


def test_gyro_burst_sharing_one_stamp_is_spaced_a_quarter_period_apart():
    arrival = ArrivalOrder(100.0)
    out = [arrival.gyro(gyro(t, stamp_ms=30))[1] for t in (10, 20, 30)]
    assert [g.stamp_ns for g in out] == [30 * MS, 32_500_000, 35 * MS]
    assert [g.angle_rad for g in out] == [gyro(t).angle_rad for t in (10, 20, 30)]
    assert arrival.gyro(gyro(40))[1].stamp_ns == 40 * MS  # caught up at the next gap


def test_bursts_with_one_stamp_keep_the_whole_rotation_and_the_last_odometry():
    a, rec = front()
    msgs: list[object] = [gyro(0), odo(0), gyro(10)]
    msgs += [odo(t, stamp_ms=100) for t in (40, 70, 100)]  # SIPs read together
    msgs += [gyro(t, stamp_ms=100) for t in range(20, 101, 10)]  # gyro packets read together
    msgs += [gyro(110)]
    assert feed(a, rec, msgs) == [0, 100]
    assert a.dropped == 2  # the burst's earlier SIPs: the last one covers them
    (call,) = rec.calls
    assert call[:2] == ("predict", 100)
    assert call[2] == pytest.approx(RATE * 0.1, abs=1e-12)  # all of it, none dropped
    assert a.gyro.discontinuities == 0 and a.decision == "fuse"


def test_odometry_waits_for_the_gyro_samples_arriving_after_it():
    a, rec = front()
    msgs: list[object] = [gyro(0), odo(0), gyro(10)]
    msgs += [gyro(t) for t in range(20, 91, 10)]
    msgs += [odo(100), gyro(100), gyro(110)]  # the gyro's sample of t=100 after the SIP
    assert feed(a, rec, msgs) == [0, 100]
    assert rec.calls == [("predict", 100, pytest.approx(RATE * 0.1, abs=1e-12))]
    # Trusting the stamps instead, the step is fused with the gyro up to 90 ms only.
    b, rec_b = front(arrival=False)
    assert feed(b, rec_b, msgs) == [0, 100]
    assert rec_b.calls == [("predict", 100, pytest.approx(RATE * 0.09, abs=1e-12))]


def test_odometry_the_gyro_caught_up_with_is_taken_at_once_else_it_waits_for_its_sample():
    a, rec = front()
    assert feed(a, rec, [gyro(0), odo(5)]) == [5]  # the gyro's next sample is due at 10
    assert feed(a, rec, [gyro(t) for t in range(10, 91, 10)] + [odo(100)]) == []  # due at 100
    assert feed(a, rec, [gyro(101)]) == [100]  # the sample that covers it releases it
    assert a.arrival is not None and a.arrival.waited == 1
    assert feed(a, rec, [odo(200)]) == []  # due at 111: held
    assert feed(a, rec, [odo(300)]) == [200]  # the gyro is silent: a newer SIP releases it
    assert feed(a, rec, [odo(1400)]) == [1400]  # silent > patience (1 s): not waited for
    assert [c[1] for c in rec.calls[-2:]] == [300, 1400]  # the held one taken first
    assert a.arrival.held is None


def test_a_late_gyro_sample_is_counted_and_its_rotation_goes_into_the_next_step():
    a, rec = front()
    msgs: list[object] = [gyro(0), odo(0)] + [gyro(t) for t in range(10, 96, 5)] + [odo(100)]
    msgs += [gyro(98)]  # read before the SIP of t=100, handed over after it
    msgs += [gyro(t) for t in range(105, 196, 5)] + [odo(200)]
    assert feed(a, rec, msgs) == [0, 100, 200]
    assert a.late == 1
    assert [c[0] for c in rec.calls] == ["predict", "predict"]
    assert rec.calls[0][2] + rec.calls[1][2] == pytest.approx(RATE * 0.195, abs=1e-12)


def test_stale_odometry_is_dropped_and_counted():
    a, rec = front()
    msgs: list[object] = [gyro(0), odo(0), gyro(10), odo(100)]
    msgs += [odo(50)]  # older than the held one
    msgs += [gyro(110), odo(80), gyro(120)]  # older than the one released
    assert feed(a, rec, msgs) == [0, 100]
    assert a.dropped == 2
    assert [c[1] for c in rec.calls] == [100]  # the filter never saw the stale SIPs


def test_gyro_clock_set_back_is_followed_not_restamped():
    arrival = ArrivalOrder(100.0)
    assert arrival.gyro(gyro(10_000))[1].stamp_ns == 10_000 * MS
    assert arrival.gyro(gyro(9_999))[1].stamp_ns == 10_002_500_000  # jitter: restamped
    assert arrival.gyro(gyro(5_000))[1].stamp_ns == 5_000 * MS  # > 1 s back: followed
    assert arrival.gyro(gyro(5_010))[1].stamp_ns == 5_010 * MS


def test_steps_the_gyro_lags_are_deferred_then_corrected_over_the_whole_interval():
    a, rec = front(arrival=False)
    feed(a, rec, [gyro(0), odo(0), odo(100), odo(200)])
    assert a.decision == "deferred"
    feed(a, rec, [gyro(t) for t in range(10, 301, 10)] + [odo(300)])
    assert a.decision == "merged" and a.deferrals == 2
    assert rec.calls[:2] == [("predict", 100, None), ("predict", 200, None)]
    assert rec.calls[2] == ("predict", 300, None)
    assert rec.calls[3] == ("correct", 0, 3, pytest.approx(RATE * 0.3, abs=1e-12))


def test_a_fresh_step_the_gyro_contradicts_is_postponed_once():
    a, rec = front(arrival=False)
    msgs: list[object] = [gyro(0), odo(0)] + [gyro(t) for t in range(10, 101, 10)]
    feed(a, rec, msgs + [odo(100, dtheta=0.3)])  # the SIP's heading is 0.3 rad off
    assert a.decision == "postponed" and a.postponed == 1
    feed(a, rec, [gyro(t) for t in range(110, 201, 10)] + [odo(200, dtheta=0.3)])
    assert a.decision == "merged"
    assert rec.calls[-1] == ("correct", 0, 2, pytest.approx(RATE * 0.2, abs=1e-12))


def test_gyro_silent_beyond_max_defer_times_out_then_restarts_unchained():
    a, rec = front(arrival=False)
    feed(a, rec, [gyro(0), odo(0)] + [odo(t) for t in range(100, 2101, 100)])
    assert a.decision == "timeout" and a.misaligned == 1 and a.gyro_stale
    feed(a, rec, [gyro(2150), gyro(2200), odo(2200)])  # the gyro re-baselines: no chain yet
    assert a.decision == "unchained" and rec.calls[-1] == ("predict", 2200, None)
    assert a.gyro_timeouts == 1 and not a.gyro_stale
    feed(a, rec, [gyro(2250), gyro(2300), odo(2300)])  # chained from the end of that step
    assert a.decision == "fuse" and rec.calls[-1][2] == pytest.approx(RATE * 0.1, abs=1e-12)


def test_an_odometry_jump_leaves_the_gyro_to_turn_over_the_lost_interval():
    a, rec = front(arrival=False)
    jumped = dataclasses.replace(odo(200), pose=Pose2D(50.0, 0.0, 0.0))  # a reset odometry
    msgs: list[object] = [gyro(0), odo(0), gyro(50), gyro(100), odo(100)]
    msgs += [gyro(150), gyro(200), jumped]
    assert feed(a, rec, msgs) == [0, 100, 200]
    assert a.odo.jumps == 1
    assert rec.calls[-1] == ("turn", pytest.approx(RATE * 0.1, abs=1e-12))


@pytest.mark.parametrize("make", [HeadingFilter, PoseEkf], ids=["heading", "pose_ekf"])
def test_filters_in_arrival_order_return_the_estimate_when_the_odometry_is_taken(make):
    f = make(initial=Pose2D(), arrival=ArrivalOrder(100.0))
    assert f.feed(gyro(0)) is None
    assert f.feed(odo(5)).stamp_ns == 5 * MS  # the gyro has caught up: at once
    assert f.feed(gyro(10)) is None and f.feed(odo(100)) is None  # held for its gyro sample
    est = f.feed(gyro(101))
    assert est is not None and est.stamp_ns == 100 * MS
    assert f.feed(odo(200, stamp_ms=190)) is None and f.feed(odo(150)) is None
    assert f.counters()["odometry_dropped"] == 1
    assert f.counters()["gyro_late"] == 0
