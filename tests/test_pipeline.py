"""Pipeline: deterministic service graph fed device messages of a simulated drive."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from drivers.sharp import STATUS_NAMES
from fakes.world import GyroErrorModel, IrErrorModel, World
from hilnav.config import load_config
from hilnav.pipeline import Pipeline
from msgs import GyroSample, IrScan, Pose2D, RobotOdometry, wrap_angle

WAYPOINTS = [(3.0, 1.5), (3.0, 4.0), (1.0, 4.0), (1.0, 1.5), (3.0, 1.5), (3.0, 4.0)]


def drive(seed: int = 0, seconds: float = 60.0):
    """Messages (topic, msg) of a robot driving a loop in the office, in arrival order,
    and the true poses at each odometry message."""
    cfg = load_config(None)
    world = World.from_name("office", seed=seed)
    robot = world.add_robot("r1", Pose2D(1.5, 1.5, 0.0))
    gyro = GyroErrorModel(seed=seed + 1)
    ir = IrErrorModel()
    rng = np.random.default_rng(seed + 2)
    mounts = np.asarray(cfg.geometry.ir_mounts_rad())
    dt, base = 0.01, robot.wheelbase_m
    out, truth = [], []
    ox = oy = oth = 0.0
    enc0 = robot.encoder_m()
    angle = 0.0
    wp = 0
    for i in range(int(seconds / dt)):
        stamp = (i + 1) * 10_000_000
        p = robot.pose
        if wp < len(WAYPOINTS):
            tx, ty = WAYPOINTS[wp]
            if math.hypot(tx - p.x, ty - p.y) < 0.15:
                wp += 1
            err = wrap_angle(math.atan2(ty - p.y, tx - p.x) - p.theta)
            w = max(-0.8, min(0.8, 2.0 * err))
            v = 0.0 if abs(err) > 0.4 else 0.4
        else:
            v = w = 0.0
        robot.command_wheels(v - 0.5 * w * base, v + 0.5 * w * base)
        world.step(dt)
        rate = gyro.sample(robot.yaw_rate_radps, dt)
        angle += rate * dt
        out.append(("gyro", GyroSample(stamp, rate, angle)))
        if i % 10 == 9:  # 10 Hz SIPs
            enc = robot.encoder_m()
            dl, dr = enc[0] - enc0[0], enc[1] - enc0[1]
            enc0 = enc
            dd, dth = 0.5 * (dl + dr), (dr - dl) / base
            ox += dd * math.cos(oth + 0.5 * dth)
            oy += dd * math.sin(oth + 0.5 * dth)
            oth = wrap_angle(oth + dth)
            lin, ang = (dl + dr) / 0.2, dth / 0.1
            out.append(("odometry", RobotOdometry(
                stamp, Pose2D(ox, oy, oth), dl / 0.1, dr / 0.1, lin, ang, 12.5,
                abs(lin) > 1e-9, True,
            )))  # fmt: skip
            truth.append((stamp, robot.pose))
        if i % 5 == 4:  # 20 Hz IR
            counts = ir.counts(world.ranges("r1", mounts, 11.0), rng)
            r, st = ir.curve.range(ir.volts(counts))
            out.append(("ir", IrScan(
                stamp, 1, i, tuple(map(float, r)),
                tuple(STATUS_NAMES[int(s)] for s in st), tuple(map(float, ir.volts(counts))),
            )))  # fmt: skip
    return out, truth


def run(cfg, inputs):
    p = Pipeline(cfg)
    outputs = []
    for topic, msg in inputs:
        outputs += p.feed(topic, msg)
    return p, outputs


def test_same_inputs_give_the_same_outputs_and_a_sensible_heading():
    inputs, truth = drive(seconds=30.0)
    cfg = load_config(None)
    m = dataclasses.replace(cfg.services.mapping, samples=60)
    cfg = dataclasses.replace(cfg, services=dataclasses.replace(cfg.services, mapping=m))
    p1, out1 = run(cfg, inputs)
    _, out2 = run(cfg, inputs)
    assert out1 == out2
    topics = {t for t, _ in out1}
    assert {"heading", "pose", "pose_box", "map", "association"} <= topics
    headings = [m for t, m in out1 if t == "heading"]
    last = headings[-1]
    true_at = dict(truth)
    stamp, true_pose = last.stamp_ns, true_at[last.stamp_ns]
    assert stamp >= truth[-2][0]  # at most the last odometry is held (for its gyro)
    assert abs(wrap_angle(last.theta_rad - true_pose.theta)) < math.radians(5)
    assert math.hypot(last.pose.x - true_pose.x, last.pose.y - true_pose.y) < 0.5
    # the map is throttled to one every publish_every_s of message time
    maps = [m for t, m in out1 if t == "map"]
    period = cfg.services.mapping.publish_every_s
    assert 30.0 / period - 2 <= len(maps) <= 30.0 / period + 1
    pose = p1.latest["pose"]
    assert pose.frame == "map" and pose.stamp_ns == stamp
    assert math.hypot(pose.pose.x - true_pose.x, pose.pose.y - true_pose.y) < 0.5
    box = p1.latest["pose_box"]
    assert box.robot == "r1"
    assert box.x.lo <= true_pose.x <= box.x.hi and box.y.lo <= true_pose.y <= box.y.hi


def test_services_switch_off_and_unknown_topics_are_ignored():
    inputs, _ = drive(seconds=5.0)
    cfg = load_config(None)
    sv = dataclasses.replace(
        cfg.services,
        mapping=dataclasses.replace(cfg.services.mapping, enabled=False),
        pose=dataclasses.replace(cfg.services.pose, enabled=False),
        localization=dataclasses.replace(cfg.services.localization, enabled=False),
    )
    p, out = run(dataclasses.replace(cfg, services=sv), inputs)
    assert {t for t, _ in out} == {"heading"}
    assert p.services == ["heading"]
    assert p.feed("cmd_vel", object()) == [] and p.feed("truth", None) == []


def test_mapping_without_association_and_a_wrong_channel_count_is_counted():
    inputs, _ = drive(seconds=5.0)
    cfg = load_config(None)
    m = dataclasses.replace(cfg.services.mapping, association=False, publish_every_s=1.0)
    cfg = dataclasses.replace(cfg, services=dataclasses.replace(cfg.services, mapping=m))
    p, out = run(cfg, inputs)
    assert [t for t, _ in out].count("map") >= 4
    bad = IrScan(10**10, 1, 0, (1.0,), ("ok",), (1.0,))
    assert p.feed("ir", bad) == [] and p.mapping.mismatched == 1


def test_bursts_after_a_stall_keep_gyro_and_encoder_intervals_aligned():
    """A stalled reader delivers 4 SIPs with one stamp, and the gyro's 40 packets with
    one stamp, in either order: the heading must come out as if nothing happened."""
    inputs, truth = drive(seconds=25.0)
    cfg = load_config(None)
    sv = dataclasses.replace(
        cfg.services,
        mapping=dataclasses.replace(cfg.services.mapping, enabled=False),
        localization=dataclasses.replace(cfg.services.localization, enabled=False),
    )
    cfg = dataclasses.replace(cfg, services=sv)

    def stalled(gyro_first: bool):
        out, held = [], []
        for topic, msg in inputs:
            t = msg.stamp_ns * 1e-9
            in_stall = any(a <= t < a + 0.4 for a in (6.0, 11.0, 17.0))  # while turning
            if in_stall:
                held.append((topic, msg))
                continue
            if held:
                stamp = msg.stamp_ns
                burst = [(tp, dataclasses.replace(m, stamp_ns=stamp)) for tp, m in held]
                burst.sort(key=lambda tm: (tm[0] != "gyro") == gyro_first)
                out += burst
                held = []
            out.append((topic, msg))
        return out

    _, clean = run(cfg, inputs)
    ref = [m for t, m in clean if t == "heading"][-1]
    for gyro_first in (True, False):
        _, out = run(cfg, stalled(gyro_first))
        last = [m for t, m in out if t == "heading"][-1]
        assert abs(wrap_angle(last.theta_rad - ref.theta_rad)) < math.radians(0.5), gyro_first


def _cp_only(**loc) -> Pipeline:
    from hilnav.config import parse_config

    cfg = parse_config(
        {
            "name": "r1",
            "fleet": ["r2"],
            "initial_pose": [0.0, 0.0, 0.0],
            "services": {
                "heading": {"enabled": False},
                "pose": {"enabled": False},
                "mapping": {"enabled": False},
                "localization": {"publish_every_s": 0.1, "gps_bound_m": 2.0, **loc},
            },
        },
        "<test>",
    )
    return Pipeline(cfg)


def _odo(i: int, x: float) -> RobotOdometry:
    return RobotOdometry(i * 100_000_000, Pose2D(x, 0.0, 0.0), 0.5, 0.5, 0.5, 0.0, 12.0, True, True)


def test_a_relative_scan_contracts_the_box_with_the_peers_boxes():
    from msgs import Interval, PoseBox, RelativeMeasurement, RelativeScan

    p = _cp_only(initial_bound_m=1.0)
    for i in range(3):
        p.feed("odometry", _odo(i, 0.05 * i))
    before = p.localization.cp.box()
    st = 2 * 100_000_000
    # r2 known within 1 cm at (0.1, 3.0); r1 is really at (0.1, 0.0): r2 at 3 m, bearing 90 deg
    p.feed_other("r2", "pose_box", PoseBox(st, "r2", Interval(0.09, 0.11), Interval(2.99, 3.01), Interval(0, 0.01)))  # fmt: skip
    seen = (RelativeMeasurement(st, "r1", "r2", 3.0, math.pi / 2, 0.02, 0.01),)
    assert p.feed("relative", RelativeScan(st, "r2", seen)) == []  # another robot's scan
    p.feed("relative", RelativeScan(st, "r1", seen))
    after = p.localization.cp.box()
    assert after.x.width < before.x.width and after.y.width < before.y.width
    assert after.x.lo <= 0.1 <= after.x.hi and after.y.lo <= 0.0 <= after.y.hi
    # no box of the peer: nothing to contract with, counted
    p.localization.drop_peer("r2")
    p.feed("relative", RelativeScan(st, "r1", seen))
    assert p.localization.cp.skipped.get("relative_no_peer_box") == 1


def test_a_gps_fix_nearer_the_next_odometry_step_waits_for_it():
    from msgs import GpsFix

    def fix(ns: int, e: float) -> GpsFix:
        return GpsFix(ns, mode=3, quality=1, east_m=e, north_m=0.0)

    held, direct = _cp_only(), _cp_only()
    for p in (held, direct):
        for i in range(3):
            p.feed("odometry", _odo(i, 0.05 * i))
    # a fix stamped at the next step: held (no box yet), given with that step's box
    assert held.feed("gps", fix(300_000_000, 0.15)) == []
    out = held.feed("odometry", _odo(3, 0.15))
    # the same as a fix given right after the step (same stamp: no widening)
    direct.feed("odometry", _odo(3, 0.15))
    direct.feed("gps", fix(300_000_000, 0.15))  # its box is not published: same stamp
    ((t, box),) = out
    assert t == "pose_box" and box.stamp_ns == 300_000_000
    assert box == direct.localization.cp.box()
    # a fix nearer the latest step is used at once
    held.feed("odometry", _odo(4, 0.2))
    held.feed("gps", fix(410_000_000, 0.2))
    assert held.localization._gps is None


def test_the_mapping_worker_takes_its_inputs_in_batches_with_the_same_outputs():
    """On a robot the mapping runs in a thread that wakes every batch_s for what came
    (not once per input); its outputs are those of the inline pipeline, in order, each
    with the tag of the input that caused it."""
    import threading
    import time

    inputs, _ = drive(seconds=12.0)
    cfg = load_config(None)
    m = dataclasses.replace(cfg.services.mapping, samples=40)
    cfg = dataclasses.replace(cfg, services=dataclasses.replace(cfg.services, mapping=m))
    inline = Pipeline(cfg)
    expected = []
    for k, (topic, msg) in enumerate(inputs):
        expected += [(t, o, k) for t, o in inline.feed(topic, msg) if t in ("map", "association")]
    got, lock = [], threading.Lock()

    def sink(t, o, tag):
        with lock:
            got.append((t, o, tag))

    threaded = Pipeline(cfg, on_mapping=sink)
    worker = threaded.worker
    assert worker is not None
    for k, (topic, msg) in enumerate(inputs):
        threaded.feed(topic, msg, tag=k)
        if k % 100 == 99:
            time.sleep(0.01)  # the device loop's pace, about
    threaded.close()
    assert worker.done
    assert got == expected
    mapped = sum(t in ("ir", "heading") for t, _ in inputs)
    assert 0 < worker.batches < mapped / 5  # woken for batches, not for each input


def test_a_mapping_input_that_raises_is_counted_and_the_worker_goes_on():
    """No single input stops the mapping thread: one that raises in the mapping service
    is handed to on_fault, and the inputs after it are mapped as without it."""
    import threading

    inputs, _ = drive(seconds=6.0)
    cfg = load_config(None)
    faults, got, lock = [], [], threading.Lock()

    def sink(t, o, tag):
        with lock:
            got.append((t, o, tag))

    p = Pipeline(cfg, on_mapping=sink, on_fault=lambda where, exc: faults.append(where))
    inline = Pipeline(cfg)
    expected = []
    for k, (topic, msg) in enumerate(inputs):
        if k == 400:  # a scan whose stamp is not a number (a broken caller)
            n = len(cfg.geometry.ir_mounts_rad())
            bad = IrScan("late", 1, 0, (1.0,) * n, ("ok",) * n, (0.0,) * n)
            p.worker.put("ir", bad, -1)
        p.feed(topic, msg, tag=k)
        expected += [(t, o, k) for t, o in inline.feed(topic, msg) if t in ("map", "association")]
    p.close()
    assert p.worker.done and faults == ["mapping"]
    assert got == expected and got
