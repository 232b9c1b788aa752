"""The robot's stamps (drivers.clock): wall time that follows the wall clock's steps
forward and never goes back."""

from __future__ import annotations

import dataclasses

from drivers.clock import SteadyWallClock
from hilnav.config import load_config
from hilnav.pipeline import Pipeline
from tests.test_pipeline import drive

S = 1_000_000_000


class Clocks:
    """A monotonic clock at ``t`` and a wall clock ``step`` away from it after ``at``."""

    def __init__(self) -> None:
        self.t, self.at, self.step = 0, None, 0

    def mono(self) -> int:
        return self.t + 5 * S  # its own origin

    def wall(self) -> int:
        stepped = self.at is not None and self.t >= self.at
        return 1_700_000_000 * S + self.t + (self.step if stepped else 0)


def test_stamps_follow_forward_steps_and_never_go_back() -> None:
    c = Clocks()
    clock = SteadyWallClock(c.wall, c.mono)
    base = c.wall()
    c.t = 3 * S
    assert clock.now_ns() == base + 3 * S  # no step: the wall clock
    c.at, c.step = 4 * S, -10 * S  # the wall clock is set back 10 s at 4 s
    stamps = []
    for k in range(40, 80):  # 4 s to 8 s, every 0.1 s
        c.t = k * S // 10
        stamps.append(clock.now_ns())
    assert all(b - a == S // 10 for a, b in zip(stamps, stamps[1:], strict=False))
    assert stamps[0] == base + 4 * S and clock.back_steps == 1  # counted once
    c.at, c.step = 9 * S, 90 * 86400 * S  # then NTP sets it 90 days forward
    c.t = 9 * S
    assert clock.now_ns() == c.wall() and clock.forward_steps == 1
    c.t = 9 * S + 300_000_000  # half a second of jitter either way is not a step
    c.step += S // 2
    assert clock.now_ns() == c.wall() - S // 2 and clock.forward_steps == 1


def test_a_wall_clock_set_back_leaves_the_heading_as_it_was() -> None:
    """The pipeline fed the stamps a daemon makes while the wall clock is set back 10 s
    mid-run gives the heading of the run without the step (with the wall clock's own
    stamps, 10 s of odometry would look out of order)."""
    inputs, _ = drive(seconds=20.0)
    c = Clocks()
    clock = SteadyWallClock(c.wall, c.mono)
    t0 = c.wall()
    c.at, c.step = 8 * S, -10 * S
    stamped = []
    for topic, msg in inputs:
        c.t = msg.stamp_ns
        stamped.append((topic, dataclasses.replace(msg, stamp_ns=clock.now_ns() - t0)))
    assert clock.back_steps == 1
    cfg = load_config(None)
    a, b = Pipeline(cfg), Pipeline(cfg)
    out_a = [o for t, m in inputs for o in a.feed(t, m)]
    out_b = [o for t, m in stamped for o in b.feed(t, m)]
    head_a = [m for t, m in out_a if t == "heading"]
    head_b = [m for t, m in out_b if t == "heading"]
    assert head_a and head_a == head_b


def test_a_step_back_is_counted_once_until_the_clocks_meet_again() -> None:
    c = Clocks()
    clock = SteadyWallClock(c.wall, c.mono)
    c.at, c.step = 1 * S, -5 * S
    for k in range(10, 30):  # 1 s to 3 s: behind all along, counted once
        c.t = k * S // 10
        clock.now_ns()
    assert clock.back_steps == 1
    c.step = 0  # the wall clock set right again: the stamps meet it, no step either way
    c.t = 4 * S
    clock.now_ns()
    c.step = -5 * S  # set back again: a second step
    c.t = 5 * S
    clock.now_ns()
    assert (clock.back_steps, clock.forward_steps) == (2, 0)
