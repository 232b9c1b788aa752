"""Dead reckoning from velocity odometry: forward speed v and yaw rate w integrated.

Each msgs.VelocityOdometry holds until the next one (zero-order hold, as a base reports
its commanded or measured velocities). Between two messages dt apart the robot moves by
the step (ds, dtheta) = (v dt, w dt) along one constant-curvature arc: eq. (2) of
ekf-vs-cp.txt with kappa = 1/2 and the chord factor (numerics.motion, exact for an arc).

No correction and no uncertainty: the output PoseEstimate has an empty covariance (the
analysis then scores its path but claims no containment). Pure: time is the messages'
stamps. A message older than the previous one, or a repeat of it, is counted
(``skipped``) and ignored (one with the same stamp and new velocities replaces them);
a step longer than ``long_step_s`` is integrated all the same (the hold is the model) and
counted in ``long_steps``.
"""

from __future__ import annotations

import math

import numpy as np

from msgs import Pose2D, PoseEstimate, VelocityOdometry, wrap_angle
from msgs.stamps import SetBackGate
from numerics.motion import motion


class VelocityDeadReckoning:
    """Integrates velocity odometry from ``initial`` (see the module docstring)."""

    def __init__(
        self,
        initial: Pose2D | None = None,
        frame: str = "map",
        source: str = "dead_reckoning",
        long_step_s: float = 1.0,
    ) -> None:
        p = initial or Pose2D(0.0, 0.0, 0.0)
        self.state = np.array([p.x, p.y, p.theta], dtype=float)
        self.frame = frame
        self.source = source
        self.long_step_ns = int(long_step_s * 1e9)
        self.long_steps = 0
        self.skipped: dict[str, int] = {}
        self._last: VelocityOdometry | None = None
        self._set_back = SetBackGate()

    def feed(self, msg: VelocityOdometry) -> PoseEstimate | None:
        """The pose at ``msg``'s stamp (the previous message's velocities held until
        then), or None for a message older than the previous one or a repeat of it."""
        prev = self._last
        if prev is not None:
            dt_ns = msg.stamp_ns - prev.stamp_ns
            if dt_ns < 0 and self._set_back.older(msg.stamp_ns, prev.stamp_ns) == "confirmed":
                self.skipped["clock_set_back"] = self.skipped.get("clock_set_back", 0) + 1
                self._last = msg  # a new baseline
                return None
            if dt_ns < 0 or (dt_ns == 0 and msg == prev):
                why = "out_of_order" if dt_ns < 0 else "duplicate"
                self.skipped[why] = self.skipped.get(why, 0) + 1
                return None
            self._set_back.newer()
            if dt_ns > self.long_step_ns:
                self.long_steps += 1
            dt = dt_ns * 1e-9
            u = np.array([prev.linear_mps * dt, prev.angular_radps * dt])
            self.state = motion(self.state, u, kappa=0.5, chord=True)
        self._last = msg
        return self.estimate(msg.stamp_ns)

    def estimate(self, stamp_ns: int) -> PoseEstimate:
        x, y, th = (float(v) for v in self.state)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(th)):
            raise ValueError("dead reckoning diverged to a non-finite pose")
        return PoseEstimate(stamp_ns, Pose2D(x, y, wrap_angle(th)), (), self.frame, self.source)
