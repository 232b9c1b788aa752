"""Dead reckoning from velocity odometry (fusion.dead_reckoning): exact arcs, the
zero-order hold, and messages out of order or repeated."""

from __future__ import annotations

import math

import numpy as np
import pytest

from fusion.dead_reckoning import VelocityDeadReckoning
from msgs import Pose2D, VelocityOdometry, wrap_angle

S = 1_000_000_000


def test_constant_velocities_follow_the_circle_exactly_whatever_the_rate() -> None:
    v, w, p0 = 0.3, 0.5, Pose2D(1.0, -2.0, 0.7)
    rng = np.random.default_rng(3)
    stamps = np.cumsum(rng.integers(5_000_000, 300_000_000, 60))  # uneven steps, ns
    dr = VelocityDeadReckoning(p0, source="r1/dead_reckoning")
    first = dr.feed(VelocityOdometry(0, v, w))
    assert first.pose == p0 and first.covariance == () and first.source == "r1/dead_reckoning"
    for st in stamps:
        est = dr.feed(VelocityOdometry(int(st), v, w))
    t = stamps[-1] / S
    r = v / w
    x = p0.x + r * (math.sin(p0.theta + w * t) - math.sin(p0.theta))
    y = p0.y - r * (math.cos(p0.theta + w * t) - math.cos(p0.theta))
    assert est.pose.x == pytest.approx(x, abs=1e-9) and est.pose.y == pytest.approx(y, abs=1e-9)
    assert est.pose.theta == pytest.approx(wrap_angle(p0.theta + w * t), abs=1e-9)
    assert est.frame == "map" and est.stamp_ns == stamps[-1]


def test_each_velocity_holds_until_the_next_message() -> None:
    dr = VelocityDeadReckoning()
    dr.feed(VelocityOdometry(0, 1.0, 0.0))
    assert dr.feed(VelocityOdometry(2 * S, 0.0, 0.0)).pose.x == pytest.approx(2.0)
    # same stamp, new velocities: no motion, they replace the held ones
    assert dr.feed(VelocityOdometry(2 * S, -0.5, 0.0)).pose.x == pytest.approx(2.0)
    est = dr.feed(VelocityOdometry(4 * S, 0.0, 0.0))
    assert est.pose.x == pytest.approx(1.0) and dr.long_steps == 2  # two 2 s steps


def test_old_and_repeated_messages_are_counted_and_ignored() -> None:
    dr = VelocityDeadReckoning()
    m = VelocityOdometry(S, 0.2, 0.1)
    assert dr.feed(m) is not None
    assert dr.feed(m) is None
    assert dr.feed(VelocityOdometry(S // 2, 5.0, 0.0)) is None
    assert dr.skipped == {"duplicate": 1, "out_of_order": 1}
    assert dr.feed(VelocityOdometry(2 * S, 0.0, 0.0)).pose.x == pytest.approx(2 * math.sin(0.1))
