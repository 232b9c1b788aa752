"""hilnav.runtime.RobotRuntime without Zenoh: the queue, the services, the peers and the
log of one robot (the daemon and every fleet robot run on it)."""

from __future__ import annotations

from hilnav.config import parse_config
from hilnav.log.reader import read_messages, read_metadata
from hilnav.runtime import RobotRuntime
from msgs import Interval, Pose2D, PoseBox, RobotOdometry


def test_the_runtime_feeds_logs_and_tracks_its_peers(tmp_path):
    cfg = parse_config(
        {
            "name": "r1",
            "fleet": ["r2"],
            "services": {n: {"enabled": False} for n in ("heading", "pose", "mapping")},
            "log": {"raw": False},
        },
        "<test>",
    )
    rt = RobotRuntime(cfg)
    rt.open_log(tmp_path / "r1.mcap", simulated=True, metadata={"scenario": "test"})
    odo = RobotOdometry(1_000, Pose2D(1.5, 1.5, 0.0), 0.0, 0.0, 0.0, 0.0, 12.0, True, True)
    box = PoseBox(900, "r2", Interval(0, 1), Interval(0, 1), Interval(0, 0.1))
    rt.put("odometry", odo, recv_ns=5_000)
    rt.put("pose_box", box, peer="r2", recv_ns=6_000)
    assert rt.drain() == 2
    assert "r2" in rt.pipeline.localization.cp.peers and rt.peers.alive == {"r2"}
    rt.put("", False, peer="r2", recv_ns=7_000)  # its liveliness token went
    rt.put("", True, peer="r2", recv_ns=8_000)  # and came back
    rt.drain()
    assert "r2" not in rt.pipeline.localization.cp.peers  # forgotten when it went
    events = [(e.wall_ns, e.robot, e.present, e.why) for e in rt.peer_events]
    assert events == [(6_000, "r2", True, "data"), (7_000, "r2", False, "token gone"),
                      (8_000, "r2", True, "token")]  # fmt: skip
    assert rt.stats.processed == 4 and rt.stats.faults == {}
    rt.close()
    got = [(m.topic, m.log_time_ns) for m in read_messages(tmp_path / "r1.mcap")]
    assert ("/r1/odometry", 5_000) in got and ("/r1/pose_box", 5_000) in got
    assert ("/r2/pose_box", 6_000) in got
    meta = read_metadata(tmp_path / "r1.mcap")
    assert meta["hilnav"]["robot"] == "r1" and meta["scenario"] == {"scenario": "test"}
