import math

import numpy as np
import pytest

from fakes.world import World, load
from msgs import Pose2D


def test_cast_hits_the_walls_of_the_room():
    plan = load("paper_room")
    d = plan.cast(np.array([[0.5, 1.5], [0.5, 1.5]]), np.array([math.pi, 0.0]), 10.0)
    assert d[0] == pytest.approx(0.5)
    assert d[1] == pytest.approx(6.5)  # east wall at x = 7
    assert np.isinf(plan.cast(np.array([[0.5, 1.5]]), np.array([math.pi]), 0.3))[0]


def test_straight_drive_is_close_to_commanded_and_deterministic():
    poses = []
    for _ in range(2):
        w = World.from_name("open_field", seed=3)
        r = w.add_robot("r1", Pose2D(0, 0, 0))
        r.command_wheels(0.5, 0.5)
        for _ in range(200):
            w.step(0.05)
        poses.append(r.pose)
    assert poses[0] == poses[1]
    assert poses[0].x == pytest.approx(5.0, rel=0.02)
    assert abs(poses[0].y) < 0.5
    assert w.time_ns == 10_000_000_000


def test_encoders_are_quantised_and_monotonic():
    w = World.from_name("open_field", seed=1)
    r = w.add_robot("r1", Pose2D(0, 0, 0))
    r.command_wheels(0.1, 0.2)
    last = (0, 0)
    for _ in range(50):
        w.step(0.01)
        assert r.left_ticks >= last[0] and r.right_ticks >= last[1]
        last = (r.left_ticks, r.right_ticks)
    el, er = r.encoder_m()
    assert el == pytest.approx(0.05, abs=1e-4) and er == pytest.approx(0.1, abs=1e-4)


def test_robot_stops_at_a_wall():
    w = World.from_name("paper_room", seed=0)
    r = w.add_robot("r1", Pose2D(1.0, 1.5, math.pi))
    r.command_wheels(0.5, 0.5)
    for _ in range(100):
        w.step(0.05)
    assert r.bumped and r.pose.x >= 0.24


def test_rasterize_marks_walls():
    plan = load("paper_room")
    grid = plan.rasterize(0.1, (-0.5, -0.5), (80, 80))
    assert grid[5, 40] == 1  # y = 0 wall
    assert grid[20, 20] == 0
    assert grid[0, 0] == -1
