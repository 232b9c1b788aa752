"""Replay of several robots at once (hilnav.replay.multi_robot) and of velocity-odometry
robots (hilnav.replay.velocity_robot): routing, peers' boxes, pipeline choice."""

from __future__ import annotations

from pathlib import Path

from hilnav.log.reader import read_messages
from hilnav.log.writer import LogWriter
from hilnav.replay.multi_robot import MultiRobotPipeline
from hilnav.replay.replayer import replay
from hilnav.replay.velocity_robot import VelocityRobotPipeline, initial_poses
from msgs import GroundTruth, Interval, Pose2D, PoseBox, RangeBearing, VelocityOdometry

S = 1_000_000_000


class BoxRobot:
    """A pipeline that publishes a box per input and records the peers' boxes it gets."""

    def __init__(self, robot: str) -> None:
        self.robot = robot
        self.peers: list[tuple[str, str]] = []

    def feed(self, topic: str, msg: object) -> list[tuple[str, object]]:
        iv = Interval(0.0, 1.0)
        return [("pose_box", PoseBox(1, self.robot, iv, iv, iv)), ("pose", msg)]

    def feed_other(self, robot: str, topic: str, msg: PoseBox) -> list[tuple[str, object]]:
        self.peers.append((robot, msg.robot))
        return [("echo", robot)]


def test_each_robots_boxes_reach_the_others_and_outputs_say_whose_they_are() -> None:
    pipe = MultiRobotPipeline(["r1", "r2", "r3"], BoxRobot)
    out = pipe.feed_robot("r2", "velocity", "m")
    assert [(r, t) for r, t, _ in out] == [
        ("r2", "pose_box"), ("r2", "pose"), ("r1", "echo"), ("r3", "echo"),
    ]  # fmt: skip
    assert pipe.pipes["r1"].peers == [("r2", "r2")] and pipe.pipes["r2"].peers == []


class FixRobot:
    """Shares "est"; on a peer's "est" answers with a "fix" (shared too) for the others."""

    shared_outputs = ("est", "fix")

    def __init__(self, robot: str) -> None:
        self.robot = robot
        self.got: list[tuple[str, str]] = []

    def feed(self, topic: str, msg: object) -> list[tuple[str, object]]:
        return [("est", self.robot)]

    def feed_other(self, robot: str, topic: str, msg: object) -> list[tuple[str, object]]:
        self.got.append((robot, topic))
        return [("fix", self.robot)] if topic == "est" else []


def test_outputs_made_in_feed_other_are_shared_too() -> None:
    pipe = MultiRobotPipeline(["r1", "r2", "r3"], FixRobot)
    out = pipe.feed_robot("r1", "velocity", "m")
    assert [(r, t) for r, t, _ in out] == [("r1", "est"), ("r2", "fix"), ("r3", "fix")]
    # each fix reached every robot but the one that made it, the first robot's "est" both
    assert pipe.pipes["r1"].got == [("r2", "fix"), ("r3", "fix")]
    assert pipe.pipes["r2"].got == [("r1", "est"), ("r3", "fix")]
    assert pipe.pipes["r3"].got == [("r1", "est"), ("r2", "fix")]


def test_velocity_robot_feeds_its_localizers_or_counts_range_bearing_unused() -> None:
    assert initial_poses({"initial_pose.r1": "1,2,0.5", "initial_pose.r2": "bad", "x": "1"}) == {
        "r1": Pose2D(1.0, 2.0, 0.5)
    }
    p = VelocityRobotPipeline("r1", Pose2D(1.0, 2.0, 0.0), ekf=False, cp=False)
    assert p.feed("landmark_range_bearing", RangeBearing(1, "r1", "l6", True, 2.0, 0.1, 6)) == []
    assert p.feed("peer_range_bearing", RangeBearing(1, "r1", "r2", False, 2.0, 0.1, 2)) == []
    assert dict(p.unused) == {"landmark_range_bearing": 1, "peer_range_bearing": 1}
    ((topic, est),) = p.feed("velocity", VelocityOdometry(S, 0.1, 0.0))
    assert topic == "dead_reckoning" and est.pose == Pose2D(1.0, 2.0, 0.0) and est.frame == "map"
    assert VelocityRobotPipeline("r2").dr.frame == "odom"  # no initial pose: its own frame
    assert VelocityRobotPipeline("r2").services == ["dead_reckoning", "mrclam_cp"]  # no EKF
    # With an initial pose, the MRCLAM EKF: it takes the range-bearing messages and
    # publishes its pose every 0.05 s from the first velocity message.
    p = VelocityRobotPipeline("r1", Pose2D(1.0, 2.0, 0.0), cp=False)
    assert p.services == ["dead_reckoning", "mrclam_ekf"]
    assert p.feed("landmark_range_bearing", RangeBearing(1, "r1", "l6", True, 2.0, 0.1, 6)) == []
    out = p.feed("velocity", VelocityOdometry(S, 0.1, 0.0))
    assert [t for t, _ in out] == ["dead_reckoning", "pose"] and not p.unused
    out = p.feed("velocity", VelocityOdometry(S + S // 10, 0.1, 0.0))
    poses = [m for t, m in out if t == "pose"]
    assert [m.stamp_ns for m in poses] == [S + S // 20, S + S // 10]
    assert poses[0].pose.x == 1.0  # the command acts 0.18 s after its stamp
    assert p.localizers[0].all_counts["before_start"] == 1


def test_a_velocity_log_without_metadata_replays_every_robot(tmp_path: Path) -> None:
    src = tmp_path / "v.mcap"
    with LogWriter(src, wall_clock=False) as w:
        for k in range(5):
            for robot in ("r1", "r2"):
                w.write(f"/{robot}/velocity", VelocityOdometry(k * S, 0.5, 0.0), k * S)
                w.write(f"/{robot}/truth", GroundTruth(k * S, robot, Pose2D(0.5 * k, 0, 0)), k * S)
    rep = replay(src, tmp_path / "out.mcap", progress=False)
    assert rep.robot == "r1,r2" and rep.pipeline_errors == 0
    # (no landmark map: the CP publishes nothing)
    assert dict(rep.outputs) == {"dead_reckoning": 10} and rep.passed == 10
    dr = [m for m in read_messages(tmp_path / "out.mcap") if m.topic.endswith("dead_reckoning")]
    assert {m.topic for m in dr} == {"/r1/dead_reckoning", "/r2/dead_reckoning"}
    assert all(m.msg.pose.x == 0.5 * m.msg.stamp_ns / S for m in dr)
    assert all(m.log_time_ns == m.msg.stamp_ns for m in dr)
