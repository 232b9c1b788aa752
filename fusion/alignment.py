"""Which gyro rotation goes with which odometry step, robust to late and bunched messages.

Both fusion filters fuse the gyro's heading change with the encoders' over the *same*
interval (ir-grid-mapping eq. 1-4, ekf-vs-cp eq. 1-4 with the gyro as an increment). On a
loaded host the reader threads stall and then deliver a burst of SIPs and a burst of gyro
packets, each burst stamped with one late read time, in either order. If a step is fused
with the gyro samples that happen to have arrived, the gyro's change covers only part of
the step (the rest arrives in the next burst) and the filter takes the missing rotation
for an encoder error; the rotation arriving later is then spread over a step it does not
belong to, or dropped: a permanent heading offset (the demo's -25 deg glitch).

:class:`GyroAlignment` enforces two rules instead:

1. *No gyro rotation is lost or counted twice while the gyro runs.* The gyro's angle
   changes telescope (fusion.increments.GyroDeltas); a change is only taken when it is
   fused, so the sum of the fused gyro changes is the gyro's total rotation.
2. *A step is fused only when the gyro has caught up with it* (its newest sample no more
   than ``max_lag_s`` older than the step's end). Until then the step is *deferred*: the
   filter predicts on the encoders alone and accumulates the deferred steps
   (:class:`Deferred`); when the gyro catches up, its change over the whole deferred
   interval is fused at once with the encoders' change over the same interval (decision
   ``"merged"``), which corrects the heading retroactively. Deferred for longer than
   ``timeout_s``: the gyro is given up for that interval (decision ``"timeout"``: the
   encoder-only prediction stands, the gyro re-baselines at its next sample, and the
   first step after that is encoder only, ``"unchained"``, because the gyro's change
   then starts inside it).

Pure bookkeeping on message stamps; no clocks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from fusion.increments import NS, GyroDelta, GyroDeltas, OdometryStep

Decision = Literal["fuse", "merged", "deferred", "timeout", "unchained", "encoder"]


@dataclass
class Deferred:
    """Encoder steps predicted without the gyro, waiting for it (sums over the interval)."""

    t0_ns: int
    x0: float
    y0: float
    steps: int = 0
    dtheta_enc: float = 0.0
    var_enc: float = 0.0
    moving: bool = False


class GyroAlignment:
    """Decides, per odometry step, how the gyro's change is used (module docstring)."""

    def __init__(self, gyro: GyroDeltas, max_lag_s: float = 0.05, max_defer_s: float = 2.0):
        self.gyro = gyro
        self.max_lag_s = max_lag_s
        self.max_defer_s = max_defer_s
        self.silent_s = math.inf
        self.deferred: Deferred | None = None
        self.chained = False
        self.merges = 0
        self.deferrals = 0
        self.postponed = 0
        self._carry: GyroDelta | None = None

    def reset(self) -> None:
        self.deferred = None
        self._carry = None
        self.chained = False

    def baseline(self) -> GyroDelta | None:
        """At an odometry baseline (first message, or a re-baseline after an odometry jump):
        the gyro starts here too. Returns the gyro's change since the last step if it
        belongs to the interval the odometry lost (chained), so the caller keeps it."""
        g = self.gyro.take()
        chained = self.chained
        if self._carry is not None and g is not None:
            g = GyroDelta(self._carry.angle_rad + g.angle_rad,
                          self._carry.covered_s + g.covered_s, self._carry.samples + g.samples)  # fmt: skip
        elif self._carry is not None:
            g = self._carry
        self._carry = None
        self.deferred = None
        self.chained = self.gyro.last is not None
        return g if chained else None

    def decide(self, step: OdometryStep) -> tuple[Decision, GyroDelta | None]:
        last = self.gyro.last_stamp_ns
        self.silent_s = math.inf if last is None else (step.t1_ns - last) * NS
        if last is None or not self.chained:
            # No gyro chain: encoder only; the chain starts at the end of a caught-up step.
            if last is not None and self.silent_s <= self.max_lag_s:
                self.gyro.take()
                self.chained = True
            self.deferred = None
            return "unchained", None
        if self.silent_s > self.max_lag_s:
            t0 = self.deferred.t0_ns if self.deferred is not None else step.t0_ns
            if (step.t1_ns - t0) * NS > self.max_defer_s:
                self.deferred = None
                self._carry = None
                self.gyro.reset()
                self.chained = False
                return "timeout", None
            self.deferrals += 1
            return "deferred", None
        g = self.gyro.take()
        if self._carry is not None:
            c, self._carry = self._carry, None
            g = c if g is None else GyroDelta(c.angle_rad + g.angle_rad,
                                              c.covered_s + g.covered_s, c.samples + g.samples)  # fmt: skip
        if g is None:  # caught up, no new sample: the gyro saw no rotation since its last take
            g = GyroDelta(0.0, 0.0, 0)
        if self.deferred is not None:
            self.merges += 1
            return "merged", g
        return "fuse", g

    def defer(self, step: OdometryStep, var_enc: float, x: float, y: float) -> Deferred:
        """Record a deferred step (x, y: the position before it)."""
        d = self.deferred
        if d is None:
            d = self.deferred = Deferred(step.t0_ns, x, y)
        d.steps += 1
        d.dtheta_enc += step.dtheta_rad
        d.var_enc += var_enc
        d.moving = d.moving or not step.at_rest
        return d

    def postpone(
        self, step: OdometryStep, gyro: GyroDelta, var_enc: float, x: float, y: float
    ) -> bool:
        """The gyro's change disagrees with the encoders' beyond the gate on a fresh step:
        if the stamps misled the alignment (a burst), the disagreement vanishes over a
        longer interval. Defer the step and carry the gyro's change to the next one.
        False (do not postpone) when the step was already part of a deferred interval."""
        if self.deferred is not None:
            return False
        self.defer(step, var_enc, x, y)
        self._carry = gyro
        self.postponed += 1
        return True

    def close(self) -> Deferred | None:
        d, self.deferred = self.deferred, None
        return d
