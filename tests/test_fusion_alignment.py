"""Regression: late, bunched, stale or jumping messages never leave a heading offset.

Reproduces the demo glitch (demo-glitch.mcap, t = 68 s) with a synthetic message sequence:
the robot turns at 1 rad/s; the host stalls 0.5 s, then delivers five SIPs all stamped with
the late read time, then 48 gyro packets all stamped with it too (arrival order as in the
log). The old filters fused the step ending at the burst with the few gyro samples read
before the stall (a fraction of the rotation), then dropped the burst's rotation as
misaligned: a permanent -25 deg offset.
"""

from __future__ import annotations

import math

import pytest

from fusion.heading import HeadingFilter
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
