"""The real-robot CP as a service per robot (localization.mrclam_cp_service): its order of
events (ticks, camera frames, commands), the boxes and sightings it exchanges with its
peers, what it skips; and the real stack on real data: ``hilnav import mrclam`` ->
``hilnav replay`` -> ``hilnav analyze`` of a slice of MRCLAM Dataset 6, whose boxes must
hold the motion-capture truth and agree with the batch runner's (bench/mrclam.py's)."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import numpy as np
import pytest

from localization.mrclam_cp_service import MrclamCpService, peer_box
from msgs import (
    Interval,
    LandmarkMap,
    PeerSighting,
    PoseBox,
    RangeBearing,
    VelocityOdometry,
    decode,
    encode,
)
from tests.conftest import HILNAV, ROOT, SHARED, hilnav_env, require

S = 1_000_000_000
DATA = SHARED / "data/mrclam/MRCLAM_Dataset6"
MARKS = {6: (3.0, 3.0), 7: (-3.0, 3.0), 8: (-3.0, -3.0), 9: (3.0, -3.0)}
TRUE = {"r1": (0.0, 0.0, 0.3), "r2": (2.0, 0.5, 2.0)}  # at rest


def _map(stamp: int = 0) -> LandmarkMap:
    ids = sorted(MARKS)
    n = len(ids)
    return LandmarkMap(
        stamp, tuple(ids), tuple(MARKS[i][0] for i in ids), tuple(MARKS[i][1] for i in ids),
        (1e-4,) * n, (0.0,) * n, (1e-4,) * n,
    )  # fmt: skip


def _seen(robot: str, stamp: int, target: str) -> RangeBearing:
    """``robot``'s exact range-bearing to a landmark (6-9) or a robot, at ``stamp``."""
    x, y, th = TRUE[robot]
    if target in TRUE:
        tx, ty, _ = TRUE[target]
        landmark, subject = False, int(target[1:])
    else:
        subject = int(target[1:])
        tx, ty = MARKS[subject]
        landmark = True
    b = math.remainder(math.atan2(ty - y, tx - x) - th, 2 * math.pi)
    # The camera reports depth r cos(b) (RangeBearingCPConfig.range_model); robots' tubes
    # read long (true depth within [0.93, 1.04] of the reading), landmarks' exactly.
    depth = math.hypot(tx - x, ty - y) * math.cos(b)
    return RangeBearing(
        stamp, robot, target, landmark, depth if landmark else depth / 0.95, b, subject
    )


def _in_view(robot: str, target: str) -> bool:
    """Whether ``target`` is in front of ``robot``'s camera (|bearing| < 80 deg)."""
    return abs(_seen(robot, 0, target).bearing_rad) < math.radians(80)


def _feed(svc: MrclamCpService, msgs: list) -> list:
    out = []
    for topic, m in msgs:
        out += svc.feed(topic, m)
    return out


def _rest(robot: str, t0: int, t1: int) -> list:
    """Commands at rest every 50 ms, and the four landmarks every 250 ms."""
    msgs = []
    for st in range(t0, t1, S // 20):
        msgs.append(("velocity", VelocityOdometry(st, 0.0, 0.0, True)))
        if (st - t0) % (S // 4) == 0:
            msgs += [
                ("landmark_range_bearing", _seen(robot, st, f"l{i}"))
                for i in MARKS
                if _in_view(robot, f"l{i}")
            ]
    return msgs


def test_ticks_wait_for_their_instant_and_the_boxes_hold_the_truth() -> None:
    svc = MrclamCpService("r1")
    # before the map: commands only, measurements counted
    assert svc.feed("landmark_range_bearing", _seen("r1", 0, "l6")) == []
    assert svc.counts["before_map"] == 1
    assert svc.feed("landmark_map", _map(0)) == []  # the ticks start here
    out = svc.feed("velocity", VelocityOdometry(S // 10, 0.0, 0.0, True))
    # the tick at 0 is out; the one at 0.1 s waits for a later stamp (commands at 0.1 s)
    assert [(t, m.stamp_ns) for t, m in out] == [("pose_box", 0)]
    assert math.isinf(out[0][1].area_m2) and out[0][1].status == "unknown"
    out = _feed(svc, _rest("r1", S // 5, 3 * S))
    ticks = [m for t, m in out if t == "pose_box"]
    assert [b.stamp_ns for b in ticks] == [k * S // 10 for k in range(1, 30)]
    x, y, th = TRUE["r1"]
    last = ticks[-1]
    assert last.status == "ok" and last.alert_stamp_ns == 0 and last.robot == "r1"
    assert last.x.lo <= x <= last.x.hi and last.y.lo <= y <= last.y.hi
    assert last.theta.lo <= th <= last.theta.hi  # (here on the branch of the truth)
    # (ranges +-13 % at 4 m and q = 1: a box of about 1.4 x 1.4 m)
    assert last.area_m2 < 3.0 and last.theta.hi - last.theta.lo < 1.0
    assert type(last.x.lo) is float
    assert decode(PoseBox, encode(last)) == last
    # a message that goes back in time is skipped; a landmark not in the map counted
    assert svc.feed("velocity", VelocityOdometry(S, 0.0, 0.0, True)) == []
    assert svc.counts["back_in_time"] == 1
    svc.feed("landmark_range_bearing", RangeBearing(3 * S, "r1", "l42", True, 1.0, 0.0, 42))
    svc.feed("velocity", VelocityOdometry(3 * S + 1, 0.0, 0.0, True))
    assert svc.counts["unknown_landmark"] == 1
    # a clock says the same without a message: the ticks up to its instant go out
    # (the tick at 3 s went out with the message stamped after it)
    assert [m.stamp_ns for _, m in svc.advance(3 * S + S // 5)] == [31 * S // 10, 32 * S // 10]
    assert svc.advance(3 * S) == [] and svc.advance(3 * S + S // 4) == []


def test_peers_exchange_boxes_and_sightings() -> None:
    """r1 sees r2: with r2's box (a peer_seen observation) and, told by r1, r2 uses it
    as an observation of itself; only robots that published a box are told."""
    a, b = MrclamCpService("r1"), MrclamCpService("r2")
    for svc in (a, b):
        svc.feed("landmark_map", _map(0))
    boxes_b = [m for t, m in _feed(b, _rest("r2", 0, 2 * S)) if t == "pose_box"]
    _feed(a, _rest("r1", 0, 2 * S))
    # r2 not heard from yet: the sighting is used by nobody and sent to nobody
    out = a.feed("peer_range_bearing", _seen("r1", 2 * S, "r2"))
    out += a.feed("velocity", VelocityOdometry(2 * S + 1, 0.0, 0.0, True))
    assert not [m for t, m in out if t == "peer_sighting"]
    assert a.counts["peer_box_unknown"] == 1 and a.counts["sighting_of_silent_robot"] == 1
    # an unbounded box is not kept (nothing to measure against), a bounded one is
    unbounded = PoseBox(S, "r2", Interval(-math.inf, math.inf), Interval(0, 1), Interval(0, 1))
    a.feed_other("r2", "pose_box", unbounded)
    assert "r2" not in a.peers and "r2" in a.heard_from
    a.feed_other("r2", "pose_box", boxes_b[-1])
    a.feed_other("r3", "pose_box", boxes_b[-1])  # claims another robot: ignored
    assert a.peers == {"r2": boxes_b[-1]}
    n_obs = a.cp.solves
    out = a.feed("peer_range_bearing", _seen("r1", 3 * S, "r2"))
    out += a.feed("velocity", VelocityOdometry(3 * S + 1, 0.0, 0.0, True))
    assert a.cp.solves > n_obs and a.counts["peer_box_unknown"] == 1
    ((topic, sighting),) = [(t, m) for t, m in out if t == "peer_sighting"]
    assert isinstance(sighting, PeerSighting) and decode(PeerSighting, encode(sighting)) == sighting
    assert (sighting.robot, sighting.observer, sighting.stamp_ns) == ("r2", "r1", 3 * S)
    assert sighting.box.x.lo <= TRUE["r1"][0] <= sighting.box.x.hi
    # r2 takes it (only from its observer, only if meant for it), at its next frame
    b.feed_other("r3", "peer_sighting", sighting)
    b.feed_other("r1", "peer_sighting", PeerSighting(3 * S, "r3", "r1", 1.0, 0.0, sighting.box))
    assert b.sightings_heard == 0
    b.feed_other("r1", "peer_sighting", sighting)
    assert b.sightings_heard == 1 and len(b.cp._heard) == 1
    out = _feed(b, _rest("r2", 3 * S, 4 * S))
    assert not b.cp._heard and b.cp.status == "ok"
    last = [m for t, m in out if t == "pose_box"][-1]
    x, y, _ = TRUE["r2"]
    assert last.x.lo <= x <= last.x.hi and last.y.lo <= y <= last.y.hi
    a.drop_peer("r2")
    assert a.peers == {}
    # alone: robot measurements are ignored, no sightings
    alone = MrclamCpService("r1", cooperative=False)
    alone.feed("landmark_map", _map(0))
    _feed(alone, _rest("r1", 0, S))
    alone.feed_other("r2", "pose_box", boxes_b[-1])
    out = alone.feed("peer_range_bearing", _seen("r1", S, "r2"))
    out += alone.feed("velocity", VelocityOdometry(S + 1, 0.0, 0.0, True))
    assert not alone.peers and not [t for t, _ in out if t == "peer_sighting"]


def test_a_published_box_keeps_its_alert_for_the_peers_quarantine() -> None:
    box = PoseBox(2 * S, "r2", Interval(0, 1), Interval(0, 1), Interval(-4.0, 4.0), "map",
                  "relaxed", S)  # fmt: skip
    pb = peer_box(box)
    assert (pb.t, pb.x, pb.th, pb.alert_t) == (2.0, (0.0, 1.0), (-4.0, 4.0), 1.0)
    assert peer_box(PoseBox(S, "r2", *(Interval(0, 1),) * 3)).alert_t == -math.inf
    svc = MrclamCpService("r1")
    svc.feed("landmark_map", _map(0))
    _feed(svc, _rest("r1", 0, S))
    svc.feed_other("r2", "pose_box", box)
    svc.feed("peer_range_bearing", _seen("r1", 2 * S, "r2"))
    svc.feed("velocity", VelocityOdometry(2 * S + 1, 0.0, 0.0, True))
    assert svc.cp.skipped["peer_box_quarantined"] == 1  # 1 s after its alert, < 5 s


def _cli(*args: str) -> dict:
    proc = subprocess.run(
        [*HILNAV, *args], capture_output=True, text=True, env=hilnav_env(), cwd=ROOT, timeout=300
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_import_replay_analyze_of_real_robots_holds_the_truth_as_the_batch_does(
    tmp_path: Path,
) -> None:
    """40 s of robots 2, 3 and 5 (who see one another), from 60 s: the replay's CP
    services exchange boxes and sightings through the log's topics; analyze finds every
    box around the motion capture, with the median areas of the batch runner."""
    require(DATA)
    from localization.mrclam import load_mrclam
    from localization.mrclam_cp import containment, run_cp

    src, dst = tmp_path / "in.mcap", tmp_path / "out.mcap"
    _cli("import", "mrclam", str(DATA), str(src), "--start", "60", "--seconds", "40",
         "--robots", "2,3,5")  # fmt: skip
    rep = _cli("replay", str(src), "--out", str(dst))
    assert rep["pipeline_errors"] == 0
    out = rep["outputs"]
    assert out["pose_box"] == 3 * 400  # every 0.1 s, the last tick waits for a later stamp
    assert out["peer_sighting"] >= 20
    summary = _cli("analyze", str(dst), "--out", str(tmp_path / "an"), "--no-plots", "--json")

    run = load_mrclam(DATA, [2, 3, 5])
    t0 = run.start_s + 60.0
    batch = run_cp(run, None, True, start_s=t0, end_s=t0 + 40.0)
    alone = run_cp(run, None, False, start_s=t0, end_s=t0 + 40.0)
    for n, tr in batch.items():
        boxes = summary["robots"][f"r{n}"]["cp_boxes"]
        assert boxes["judged"] >= 390 and boxes["contained_fraction"] >= 0.995, boxes
        pose, has = run.robots[n].truth_at(tr.t)
        assert containment(tr, pose)[has].mean() >= 0.995
        w = tr.box[has, 1] - tr.box[has, 0]
        area = float(np.median(w[:, 0] * w[:, 1]))
        assert boxes["judged_median_area_m2"] == pytest.approx(area, rel=0.02), (n, area)
        assert area < 20.0  # bounded: the landmarks were found
    # cooperation made the boxes of the robots that were seen smaller
    single = {n: np.median(np.prod(tr.box[:, 1, :2] - tr.box[:, 0, :2], axis=1))
              for n, tr in alone.items()}  # fmt: skip
    assert sum(summary["robots"][f"r{n}"]["cp_boxes"]["area_m2"]["median"] for n in single) < sum(
        single.values()
    )
