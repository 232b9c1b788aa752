"""The velocity-command gate: which bus commands reach the wheels, and when the robot stops.

Pure (the caller passes the monotonic time), so the rules are tested without a robot.
:meth:`CmdVelGate.accept` takes a decoded command, refuses it if any number is not finite
or the service loop has stalled, and clamps it to the configured limits.
:meth:`CmdVelGate.check` says when a moving robot must be stopped: no valid command for
``timeout_s``, or no heartbeat from the service loop for ``stall_s``. The daemon runs
``check`` on a timer thread of its own, outside the service loop, so a loop that dies or
hangs still stops the wheels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from msgs import VelocityCommand


@dataclass(frozen=True)
class CmdVelLimits:
    timeout_s: float = 0.5
    stall_s: float = 0.5
    max_linear_mps: float = 0.75
    max_angular_radps: float = 1.5


def _clamp(v: float, m: float) -> float:
    return max(-m, min(m, v))


@dataclass
class CmdVelGate:
    """Validate and clamp commands; decide when to stop (see the module docstring)."""

    limits: CmdVelLimits = field(default_factory=CmdVelLimits)
    moving: bool = False
    last_cmd_s: float = -math.inf
    heartbeat_s: float | None = None
    received: int = 0
    rejected: int = 0
    timeouts: int = 0
    stalls: int = 0
    last_reason: str = ""

    def heartbeat(self, now: float) -> None:
        """The service loop is alive at ``now``."""
        self.heartbeat_s = now

    def stalled(self, now: float) -> bool:
        return self.heartbeat_s is not None and now - self.heartbeat_s > self.limits.stall_s

    def accept(self, cmd: VelocityCommand, now: float) -> VelocityCommand | None:
        """The clamped command to send to the wheels, or None (counted in ``rejected``)."""
        vals = (cmd.linear_mps, cmd.angular_radps, cmd.left_mps or 0.0, cmd.right_mps or 0.0)
        if not all(isinstance(v, int | float) and math.isfinite(v) for v in vals):
            return self._reject("not a finite command")
        if self.stalled(now):
            return self._reject("service loop stalled")
        lin, ang = self.limits.max_linear_mps, self.limits.max_angular_radps
        c = VelocityCommand(
            cmd.stamp_ns,
            _clamp(cmd.linear_mps, lin),
            _clamp(cmd.angular_radps, ang),
            None if cmd.left_mps is None else _clamp(cmd.left_mps, lin),
            None if cmd.right_mps is None else _clamp(cmd.right_mps, lin),
            cmd.source,
        )
        self.received += 1
        self.last_cmd_s = now
        wheels = (c.left_mps or 0.0, c.right_mps or 0.0)
        self.moving = any(abs(v) > 1e-9 for v in (c.linear_mps, c.angular_radps, *wheels))
        return c

    def _reject(self, reason: str) -> None:
        self.rejected += 1
        self.last_reason = reason
        return None

    def next_check(self) -> float:
        """The earliest time :meth:`check` can stop the robot (inf while it is not moving):
        a watchdog need not look before then, unless a command or a heartbeat comes."""
        if not self.moving:
            return math.inf
        due = self.last_cmd_s + self.limits.timeout_s
        if self.heartbeat_s is not None:
            due = min(due, self.heartbeat_s + self.limits.stall_s)
        return due

    def check(self, now: float) -> str | None:
        """``"timeout"`` or ``"stall"`` once when a moving robot must stop now, else None."""
        if not self.moving:
            return None
        if self.stalled(now):
            self.stalls += 1
            reason = "stall"
        elif now - self.last_cmd_s >= self.limits.timeout_s:
            self.timeouts += 1
            reason = "timeout"
        else:
            return None
        self.moving = False
        self.last_reason = reason
        return reason

    def halt(self) -> None:
        """Forget the motion (the daemon is stopping the robot for good)."""
        self.moving = False
