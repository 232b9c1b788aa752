"""hilnav.runtime.RobotRuntime without Zenoh: the queue, the services, the peers and the
log of one robot (the daemon and every fleet robot run on it)."""

from __future__ import annotations

from hilnav.bus import free_tcp_port
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


class _Order:
    """A sink that keeps each record's topic and which outputs the pipeline had made."""

    def __init__(self, rt_of):
        self.rt_of, self.seen = rt_of, []

    def write_records(self, records, log_time_ns, publish_time_ns=None):
        self.seen.append((records[0].topic, log_time_ns, set(self.rt_of().pipeline.latest)))

    def close(self):
        pass


def test_a_device_read_is_one_entry_and_outputs_go_out_as_they_are_made():
    cfg = parse_config(
        {
            "name": "r1",
            "services": {n: {"enabled": False} for n in ("localization", "mapping")},
            "log": {"raw": False},
        },
        "<test>",
    )
    rts: list[RobotRuntime] = []
    order = _Order(lambda: rts[0])
    rt = RobotRuntime(cfg, sinks={"order": order}, queue_size=2)
    rts.append(rt)
    odo = [
        RobotOdometry(1_000_000_000 + k * 100_000_000, Pose2D(1.5 + 0.01 * k, 1.5, 0.0),
                      0.1, 0.0, 0.0, 0.0, 12.0, True, True)
        for k in range(4)
    ]  # fmt: skip
    rt.put_read([("odometry", odo[0]), ("odometry", odo[1])])  # one read: one entry
    rt.put("odometry", odo[2])
    rt.put_read([("odometry", odo[3])])  # the queue holds 2 entries: dropped
    assert rt.stats.dropped == 1
    assert rt.drain() == 3 and rt.stats.processed == 3
    topics = [t for t, _, _ in order.seen]
    assert topics == ["/r1/odometry", "/r1/heading", "/r1/pose"] * 3  # no gyro: none waits
    # the read's items share one receive time (log time), outputs take their input's
    assert order.seen[0][1] == order.seen[2][1] == order.seen[3][1] == order.seen[5][1]
    # the heading went out before the pose service ran on the same input
    assert "pose" not in order.seen[1][2] and "pose" in order.seen[2][2]
    rt.close()


class _Puts:
    """A sink that keeps, for each message logged, its records and how many messages the
    robot's bus had put by then."""

    def __init__(self, rt_of):
        self.rt_of, self.seen = rt_of, []

    def write_records(self, records, log_time_ns, publish_time_ns=None):
        bus = self.rt_of().bus
        self.seen.append(([(r.topic, r.data) for r in records], bus.stats.published))

    def close(self):
        pass


def _odometry_read(prompt: frozenset[str]) -> _Puts:
    port = free_tcp_port()
    cfg = parse_config(
        {
            "name": "r1",
            "services": {n: {"enabled": False} for n in ("localization", "mapping")},
            "log": {"raw": False},
            "zenoh": {"listen": [f"tcp/127.0.0.1:{port}"]},
        },
        "<test>",
    )
    rts: list[RobotRuntime] = []
    sink = _Puts(lambda: rts[0])
    rt = RobotRuntime(cfg, sinks={"log": sink})
    rts.append(rt)
    rt.open_bus()
    try:
        for k in range(3):
            odo = RobotOdometry(1_000_000_000 + k * 100_000_000, Pose2D(1.5 + 0.01 * k, 1.5, 0.1),
                                0.1, 0.0, 0.0, 0.0, 12.0, True, True)  # fmt: skip
            later: list | None = [] if prompt else None  # None: each logged as it comes
            rt.handle_read([("odometry", odo)], 5_000 + k, later=later, prompt=prompt)
            rt.emit_later(later or [])
    finally:
        rt.close()
    assert rt.stats.faults == {}
    return sink


def test_a_prompt_read_and_its_outputs_are_all_put_before_any_is_logged():
    """The daemon's odometry read: odometry, heading and pose go on the bus as each is
    made, and are logged after the last put (nothing but their encodings before the
    pose's put), with the same records, views included, as when logged at once."""
    prompt = _odometry_read(frozenset({"odometry"}))
    plain = _odometry_read(frozenset())
    topics = [records[0][0] for records, _ in prompt.seen]
    assert topics == ["/r1/odometry", "/r1/heading", "/r1/pose"] * 3
    assert [puts for _, puts in prompt.seen] == [3] * 3 + [6] * 3 + [9] * 3
    assert [puts for _, puts in plain.seen] == list(range(1, 10))  # each logged at its put
    assert [records for records, _ in prompt.seen] == [records for records, _ in plain.seen]
    assert any(len(records) > 1 for records, _ in prompt.seen)  # views logged too
