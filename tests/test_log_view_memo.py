"""hilnav.log.encoding.ViewMemo: the encoders of one process (a fleet host's robots, each
logging every peer's box) share a message's records and views; what each writes is the
same as without the memo."""

from __future__ import annotations

import pytest

from hilnav.fleet.host import peer_classes
from hilnav.log.encoding import Encoder, ViewMemo
from msgs import Interval, Pose2D, PoseBox, PoseEstimate, RobotOdometry


def _box(robot: str, i: int) -> PoseBox:
    return PoseBox(
        10**18 + i, robot, Interval(0.1 * i, 0.1 * i + 1.5), Interval(-2.0, -0.5),
        Interval(-0.2 + 6.3 * (i % 3), 0.3 + 6.3 * (i % 3)),
    )  # fmt: skip


def test_shared_records_equal_those_of_an_encoder_alone():
    memo = ViewMemo(peer_classes())
    robots = [Encoder(memo=memo) for _ in range(4)]
    alone = Encoder()
    for i in range(30):
        box = _box(f"r{i % 5}", i)
        copy = PoseBox(box.stamp_ns, box.robot, box.x, box.y, box.theta)  # equal, not same
        topic = f"/{box.robot}/pose_box"
        want = alone.encode(topic, box)
        assert len(want) == 2 and want[1].topic == f"/{box.robot}/fox/pose_box"
        for enc in robots:  # the very message: its records; an equal one: its views
            assert enc.encode(topic, box) == want
        for enc in robots:
            assert enc.encode(topic, copy) == want
    # each message's records were made once; the others were found
    assert memo.hits == 30 * (2 * 4 - 1)


def test_messages_of_other_classes_and_views_that_keep_state_are_not_shared():
    memo = ViewMemo(peer_classes())
    a, b = Encoder(memo=memo), Encoder(memo=memo)
    odo = RobotOdometry(5, Pose2D(1.0, 2.0, 0.5), 0.0, 0.0, 0.0, 0.0, 12.0, True, True)
    a.encode("/r1/odometry", odo)
    est = PoseEstimate(6, Pose2D(1.5, 2.5, 0.4), (0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.001))
    # b never saw r1's odometry: no map -> odom transform, as an encoder alone
    assert len(b.encode("/r1/pose", est)) == 2 and len(a.encode("/r1/pose", est)) == 3
    assert memo.hits == 0
    with pytest.raises(ValueError, match="PoseEstimate"):
        ViewMemo([PoseBox, PoseEstimate])
    # an encoder without views never takes (nor leaves) a message's views
    bare = Encoder(views=False, memo=memo)
    assert len(bare.encode("/r2/pose_box", _box("r2", 1))) == 1
    assert len(a.encode("/r2/pose_box", _box("r2", 1))) == 2
