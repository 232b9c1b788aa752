"""The velocity-command gate (pure) and the boundary checks of msgs.decode that keep a
hostile or broken peer's command away from the wheels."""

from __future__ import annotations

import json
import math

import pytest

import msgs
from hilnav.cmdvel import CmdVelGate, CmdVelLimits
from msgs import Interval, PoseBox, VelocityCommand


def gate() -> CmdVelGate:
    return CmdVelGate(CmdVelLimits(timeout_s=0.5, stall_s=0.3, max_linear_mps=0.5,
                                   max_angular_radps=1.0))  # fmt: skip


def test_commands_are_clamped_and_non_finite_ones_refused():
    g = gate()
    c = g.accept(VelocityCommand(1, 3.0, -9.0, source="op"), now=0.0)
    assert c is not None and (c.linear_mps, c.angular_radps) == (0.5, -1.0)
    w = g.accept(VelocityCommand(1, left_mps=-2.0, right_mps=0.1), now=0.0)
    assert w is not None and (w.left_mps, w.right_mps) == (-0.5, 0.1)
    for bad in (math.nan, math.inf, -math.inf):
        assert g.accept(VelocityCommand(1, bad, 0.0), now=0.0) is None
        assert g.accept(VelocityCommand(1, 0.0, 0.0, left_mps=bad, right_mps=0.0), now=0.0) is None
    assert (g.received, g.rejected) == (2, 6)


def test_a_moving_robot_stops_once_after_the_timeout():
    g = gate()
    g.accept(VelocityCommand(1, 0.3, 0.0), now=10.0)
    assert g.check(10.4) is None
    assert g.check(10.5) == "timeout"
    assert g.check(11.0) is None  # once
    g.accept(VelocityCommand(1, 0.0, 0.0), now=12.0)  # a stop command: nothing to time out
    assert g.check(20.0) is None and g.timeouts == 1


def test_a_stalled_service_loop_stops_the_robot_and_blocks_new_commands():
    g = gate()
    g.heartbeat(0.0)
    assert g.accept(VelocityCommand(1, 0.3, 0.0), now=0.1) is not None
    g.heartbeat(0.2)
    assert g.check(0.45) is None  # loop came round 0.25 s ago, command 0.35 s old
    assert g.check(0.55) == "stall"  # 0.35 s without a heartbeat (stall_s = 0.3)
    assert g.accept(VelocityCommand(1, 0.3, 0.0), now=0.6) is None
    assert g.last_reason == "service loop stalled"
    g.heartbeat(0.7)  # the loop is back: commands are obeyed again
    assert g.accept(VelocityCommand(1, 0.3, 0.0), now=0.7) is not None


@pytest.mark.parametrize(
    ("payload", "why"),
    [
        ({"stamp_ns": 2**64, "linear_mps": 0.5}, "64 bits"),
        ({"stamp_ns": 2**63, "linear_mps": 0.5}, "64 bits"),
        ({"stamp_ns": -1, "linear_mps": 0.5}, "negative"),
        ({"stamp_ns": 1, "linear_mps": "nan"}, "finite"),
        ({"stamp_ns": 1, "linear_mps": 1e400}, "finite"),  # json reads 1e400 as inf
        ({"stamp_ns": 1, "angular_radps": 10**400}, "range"),
    ],
)
def test_out_of_range_commands_do_not_decode(payload, why):
    with pytest.raises(msgs.DecodeError, match=why):
        msgs.decode(VelocityCommand, json.dumps(payload).encode())


def test_nan_literal_and_deep_nesting_and_huge_payloads_do_not_decode():
    with pytest.raises(msgs.DecodeError, match="finite"):
        msgs.decode(VelocityCommand, b'{"stamp_ns": 1, "linear_mps": NaN}')
    deep = b'{"stamp_ns": 1, "source": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    with pytest.raises(msgs.DecodeError, match="nested too deeply"):
        msgs.decode(VelocityCommand, deep)
    with pytest.raises(msgs.DecodeError, match="limit"):
        msgs.decode(VelocityCommand, b" " * 100 + b"{}", max_bytes=64)


def test_pose_boxes_may_be_unbounded_but_not_nan():
    box = PoseBox(5, "r2", Interval(0, 1), Interval(0, 1), Interval(-math.inf, math.inf))
    assert msgs.decode(PoseBox, msgs.encode(box)) == box
    bad = PoseBox(5, "r2", Interval(0, math.nan), Interval(0, 1), Interval(0, 1))
    with pytest.raises(msgs.DecodeError, match="no-nan"):
        msgs.decode(PoseBox, msgs.encode(bad))
