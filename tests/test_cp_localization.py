"""CP localization (eq. 5): guaranteed containment on seeded runs, sliding-window
smoothing, outlier-tolerant relaxed intersection, cooperative contraction, message API."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fakes.world.paper_scenario import simulate
from localization.cp import CPConfig, CPLocalizer
from localization.interval import IV
from localization.odometry import motion
from msgs import GpsFix, GyroSample, Interval, Pose2D, PoseBox, RelativeMeasurement, RobotOdometry


def _cfg(sc, **kw) -> CPConfig:
    b = sc.bounds
    return CPConfig(
        wheelbase_m=sc.wheelbase_m,
        wheel_abs_bound_m=b.wheel_abs_m,
        wheel_rel_bound=b.wheel_rel,
        gps_bound_m=b.gps_m,
        gyro_bound_rad=b.gyro_rad,
        **kw,
    )


def _start(sc, i, cfg) -> CPLocalizer:
    b = sc.bounds
    cp = CPLocalizer(cfg, robot=sc.names[i])
    cp.start(
        0,
        IV.around(sc.gps[i, 0, 0], b.gps_m),
        IV.around(sc.gps[i, 0, 1], b.gps_m),
        IV.around(sc.gyro[i, 0], b.gyro_rad),
    )
    return cp


def _own(cp, sc, i, s):
    b, st = sc.bounds, int(sc.stamps_ns[s])
    if s:
        cp.step(st, sc.dsr[i, s], sc.dsl[i, s])
    cp.heading(st, IV.around(sc.gyro[i, s], b.gyro_rad))
    if not np.isnan(sc.gps[i, s, 0]):
        cp.gps(st, *sc.gps[i, s])


def _contains(x, y, th, t) -> bool:
    return bool(x.contains(t[0]) and y.contains(t[1]) and th.contains(t[2]))


@pytest.mark.parametrize("seed,window", [(1, 20), (2, 1), (3, 40)])
def test_single_cp_contains_truth_at_every_step(seed, window):
    sc = simulate(duration_s=8.0, seed=seed, gps_every=2)
    for i in range(3):
        cp = _start(sc, i, _cfg(sc, window=window))
        widths = []
        for s in range(sc.steps):
            _own(cp, sc, i, s)
            x, y, th = cp.current()
            assert _contains(x, y, th, sc.truth[i, s]), (i, s)
            widths.append(float(x.width()))
        assert widths[-1] < 0.5 * widths[0]  # the GPS boxes intersect down
        # The smoothed window contains the truth too.
        stamps, wx, wy, wth = cp.window_arrays()
        k0 = sc.steps - len(stamps)
        for k in range(len(stamps)):
            assert _contains(wx[k], wy[k], wth[k], sc.truth[i, k0 + k])


def test_later_measurements_tighten_earlier_boxes():
    sc = simulate(duration_s=6.0, seed=4)
    cp = _start(sc, 0, _cfg(sc, window=80))
    at_the_time = []
    for s in range(sc.steps):
        _own(cp, sc, 0, s)
        at_the_time.append(float(cp.current()[0].width()))
    smoothed = cp.window_boxes()
    k0 = sc.steps - len(smoothed)
    w_smooth = np.array([b.x.width for b in smoothed])
    w_filt = np.array(at_the_time[k0:])
    assert np.all(w_smooth <= w_filt + 1e-9)
    assert np.mean(w_smooth[:-5]) < 0.8 * np.mean(w_filt[:-5])
    for k, b in enumerate(smoothed):
        t = sc.truth[0, k0 + k]
        assert b.x.contains(t[0]) and b.y.contains(t[1])


def test_gps_jump_is_tolerated_and_reported():
    jump_step = 25
    sc = simulate(duration_s=6.0, seed=7, gps_jumps=((0, jump_step, 15.0, -12.0),))
    cp = _start(sc, 0, _cfg(sc, window=30, gps_outliers=1))
    for s in range(sc.steps):
        _own(cp, sc, 0, s)
        x, y, th = cp.current()
        assert not bool(x.is_empty() or y.is_empty())
        assert _contains(x, y, th, sc.truth[0, s]), s
    assert cp.dropped_gps == [int(sc.stamps_ns[jump_step])]
    assert cp.relaxations == 0
    # Without tolerance the plain intersection would be empty: the solver then relaxes
    # on its own (and counts it) rather than returning an empty box.
    cp0 = _start(sc, 0, _cfg(sc, window=30, gps_outliers=0))
    for s in range(sc.steps):
        _own(cp0, sc, 0, s)
        x, y, _ = cp0.current()
        assert not bool(x.is_empty() or y.is_empty())
    assert cp0.relaxations > 0 and int(sc.stamps_ns[jump_step]) in cp0.dropped_gps


def test_cooperative_cp_shrinks_and_contains_truth():
    sc = simulate(duration_s=6.0, seed=8)
    b = sc.bounds
    single = [_start(sc, i, _cfg(sc, window=20)) for i in range(3)]
    multi = [_start(sc, i, _cfg(sc, window=20)) for i in range(3)]
    area_s = area_m = 0.0
    for s in range(sc.steps):
        st = int(sc.stamps_ns[s])
        for i in range(3):
            _own(single[i], sc, i, s)
            _own(multi[i], sc, i, s)
        cur = [c.current() for c in multi]
        for i, cp in enumerate(multi):
            js = [j for j in range(3) if j != i]
            px = IV.of([float(cur[j][0].lo) for j in js], [float(cur[j][0].hi) for j in js])
            py = IV.of([float(cur[j][1].lo) for j in js], [float(cur[j][1].hi) for j in js])
            cp.relative(
                st,
                px,
                py,
                IV.around(sc.rel_range[i, js, s], b.range_m),
                IV.around(sc.rel_bearing[i, js, s], b.bearing_rad),
            )
        for i in range(3):
            x, y, th = multi[i].current()
            assert _contains(x, y, th, sc.truth[i, s]), (i, s)
            area_m += float(x.width() * y.width())
            xs, ys, _ = single[i].current()
            area_s += float(xs.width() * ys.width())
    assert area_m < 0.9 * area_s


def _odometry_msgs(sc, i):
    pose = Pose2D()
    out = []
    for s in range(sc.steps):
        if s:
            p = motion(
                np.array([pose.x, pose.y, pose.theta]), (sc.dsr[i, s], sc.dsl[i, s]), sc.wheelbase_m
            )
            pose = Pose2D(p[0], p[1], p[2])
        out.append(RobotOdometry(int(sc.stamps_ns[s]), pose, 1.0, 1.0, 1.0, 0.0, 12.0, True, True))
    return out


def test_message_level_api():
    sc = simulate(duration_s=5.0, seed=9)
    b = sc.bounds
    t0 = sc.truth[0, 0]
    init = PoseBox(
        0, "r1", Interval(t0[0] - 3, t0[0] + 3), Interval(t0[1] - 3, t0[1] + 3), Interval(-0.1, 0.1)
    )
    cp = CPLocalizer(_cfg(sc, window=20, gps_outliers=1), robot="r1", initial=init)
    peer = PoseBox(0, "r2", Interval(-100, 100), Interval(-100, 100), Interval(-4, 4))
    assert cp.feed(GyroSample(0, 0.0, 0.0)) is None  # before the first step: counted
    for s, odo in enumerate(_odometry_msgs(sc, 0)):
        st = odo.stamp_ns
        box = cp.feed(odo)
        assert isinstance(box, PoseBox) and box.robot == "r1" and box.stamp_ns == st
        cp.feed(GyroSample(st, 0.0, float(sc.gyro[0, s])))
        box = cp.feed(
            GpsFix(st, mode=3, east_m=float(sc.gps[0, s, 0]), north_m=float(sc.gps[0, s, 1]))
        )
        t = sc.truth[0, s]
        assert box.x.contains(t[0]) and box.y.contains(t[1]) and box.theta.contains(t[2])
        assert -math.pi - 0.1 < 0.5 * (box.theta.lo + box.theta.hi) <= math.pi + 0.1
    assert cp.feed(GpsFix(1, mode=1)) is None and cp.skipped["gps_no_fix"] == 1
    # Relative measurement to a peer whose box is old: widened by the speed bound.
    truth_r2 = sc.truth[1, -1]
    rm = RelativeMeasurement(
        int(sc.stamps_ns[-1]),
        "r1",
        "r2",
        float(sc.rel_range[0, 1, -1]),
        float(sc.rel_bearing[0, 1, -1]),
        b.range_m,
        b.bearing_rad,
    )
    assert cp.feed(rm) is None and cp.skipped["relative_no_peer_box"] == 1
    cp.feed(peer)
    tight = PoseBox(
        int(sc.stamps_ns[-1]) - 200_000_000,
        "r2",
        Interval(truth_r2[0] - 0.1, truth_r2[0] + 0.1),
        Interval(truth_r2[1] - 0.1, truth_r2[1] + 0.1),
        Interval(-4, 4),
    )
    cp.feed(tight)
    assert cp.peers["r2"] is tight
    before = cp.box()
    after = cp.feed(rm)
    t = sc.truth[0, -1]
    assert after is not None and after.x.contains(t[0]) and after.y.contains(t[1])
    assert after.area_m2 <= before.area_m2
    cp.drop_peer("r2")
    assert "r2" not in cp.peers
    assert cp.feed("garbage") is None and cp.skipped["unhandled_str"] == 1


def test_pipeline_adapter_throttles_and_takes_peer_boxes():
    from hilnav.config import parse_config
    from hilnav.services import LocalizationAdapter

    sc = simulate(duration_s=2.0, seed=10)
    cfg = parse_config({"services": {"localization": {"publish_every_s": 0.5}}})
    svc = LocalizationAdapter(cfg)
    outs = []
    for s, odo in enumerate(_odometry_msgs(sc, 0)):
        outs += svc.feed("odometry", odo)
        outs += svc.feed("gyro", GyroSample(odo.stamp_ns, 0.0, float(sc.gyro[0, s])))
        outs += svc.feed("ir", object())  # not ours: ignored
    stamps = [m.stamp_ns for t, m in outs]
    assert all(t == "pose_box" for t, _ in outs)
    assert len(outs) == 5 and all(
        b - a >= 500_000_000 for a, b in zip(stamps, stamps[1:], strict=False)
    )
    peer = PoseBox(1, "r2", Interval(0, 1), Interval(0, 1), Interval(0, 1))
    assert svc.feed_other("r2", "pose_box", peer) == [] and svc.cp.peers["r2"] is peer
    svc.feed_other("r9", "pose_box", peer)  # claims another robot: ignored
    assert "r9" not in svc.cp.peers
    svc.drop_peer("r2")
    assert not svc.cp.peers


def test_spinning_robot_with_wrapped_gyro_and_unknown_initial_heading():
    from fakes.world.paper_scenario import RobotSpec

    spin = (RobotSpec("s1", Pose2D(0.0, 0.0, 2.5), 1.0, 0.8),)  # ~0.6 rad/s: > 2 turns
    sc = simulate(spin, duration_s=12.0, seed=12)
    b = sc.bounds
    cp = CPLocalizer(_cfg(sc, window=15), robot="s1")
    cp.start(
        0,
        IV.around(sc.gps[0, 0, 0], b.gps_m),
        IV.around(sc.gps[0, 0, 1], b.gps_m),
        IV.of(-math.pi, math.pi),
    )
    for s in range(sc.steps):
        st = int(sc.stamps_ns[s])
        if s:
            cp.step(st, sc.dsr[0, s], sc.dsl[0, s])
        wrapped = math.remainder(float(sc.gyro[0, s]), 2 * math.pi)
        cp.heading(st, IV.around(wrapped, b.gyro_rad))
        cp.gps(st, *sc.gps[0, s])
        x, y, th = cp.current()
        t = sc.truth[0, s]
        k = round((float(th.mid()) - t[2]) / (2 * math.pi))
        assert _contains(x, y, th, (t[0], t[1], t[2] + 2 * math.pi * k)), s
        assert float(th.width()) < 2 * b.gyro_rad + 1e-9
    assert abs(sc.truth[0, -1, 2] - sc.truth[0, 0, 2]) > 2 * math.pi
