"""Messages in arrival order, as the stream drivers stamp them, put back in stamp order.

The stream drivers stamp every message decoded from one read with that read's time. On a
loaded host a reader stalls and then delivers a burst of SIPs and a burst of gyro
packets, each burst with one late stamp, in either order. :class:`ArrivalOrder` is the
first stage of the gyro/odometry alignment front end (fusion.alignment), used when the
messages come from the drivers (the pipeline); four rules:

1. *Gyro stamps strictly increase*, at least a quarter of the nominal period apart: two
   packets read together share a stamp or come microseconds apart, which
   fusion.increments.GyroDeltas would drop (not newer) or take for a discontinuity (a
   large angle change over a tiny interval, replaced by rate x dt: real rotation lost).
   The angles are untouched; the restamped times catch up with the real ones at the next
   gap. A stamp more than a second older than the last is a clock set back (msgs.stamps): it is
   followed, not restamped.
2. *Odometry waits only for a gyro sample that is due*: an odometry message is taken the
   moment it arrives when the gyro has caught up with it, i.e. its next sample is not due
   yet (the newest gyro stamp as read + one nominal period > the odometry's stamp: every
   sample up to the odometry's time is in). Otherwise the sample covering it is on its
   way, and the odometry is held until a gyro sample with a strictly newer stamp arrives
   (every sample up to its time has then been taken: a burst read at once shares one
   stamp) or a newer odometry message does (the gyro is silent: carry on without it); a
   gyro silent for longer than ``patience_s`` is not waited for. So an odometry message
   (and the pose made of it) waits for the arrival of its matching gyro sample, not a
   fixed hold, and not at all when the gyro is ahead of it.
3. *Of a burst of odometry with one stamp only the last is kept*: odometry poses are
   cumulative, so it covers the whole burst.
4. *Odometry older than the held or the last released message is dropped*, unless it is
   more than a second older and the next one continues from it (msgs.stamps: a clock
   set back), which is followed after the held one is released.

A gyro sample that arrives after the odometry it precedes was taken (its stamp at or
before that odometry's: stamp jitter beyond the rule-2 margin, or readers racing) is
counted (``late``) and never lost: fusion.increments.GyroDeltas adds its rotation to the next
step's gyro change, which corrects the heading at that step (the gyro's changes telescope).

Drops under rules 3 and 4 are counted (``dropped``). Pure: no clocks, times are the
message stamps (integer ns); the output depends only on the input sequence.
"""

from __future__ import annotations

from msgs import GyroSample, RobotOdometry
from msgs.stamps import SetBackGate, set_back


class ArrivalOrder:
    """Gyro restamping and odometry holding (see the module docstring)."""

    def __init__(self, gyro_rate_hz: float, patience_s: float = 1.0) -> None:
        if not gyro_rate_hz > 0.0:
            raise ValueError(f"ArrivalOrder: gyro_rate_hz must be > 0, got {gyro_rate_hz!r}")
        if not patience_s >= 0.0:
            raise ValueError(f"ArrivalOrder: patience_s must be >= 0, got {patience_s!r}")
        self.period_ns = int(1e9 / gyro_rate_hz)
        self.spacing_ns = int(0.25e9 / gyro_rate_hz)
        self.patience_ns = int(patience_s * 1e9)
        self.held: RobotOdometry | None = None
        self.dropped = 0
        self.late = 0  # gyro samples stamped at or before odometry already taken
        self.waited = 0  # odometry messages held for their gyro sample
        self._gyro_ns: int | None = None  # the newest gyro stamp, restamped
        self._gyro_read_ns: int | None = None  # the newest gyro stamp as read
        self._released_ns: int | None = None
        self._set_back = SetBackGate()

    def gyro(self, g: GyroSample) -> tuple[RobotOdometry | None, GyroSample]:
        """The odometry to take before this sample (rule 2), and the sample restamped (rule 1)."""
        done = self._released_ns
        if done is not None and g.stamp_ns <= done and not set_back(g.stamp_ns, done):
            self.late += 1
        self._gyro_read_ns = g.stamp_ns
        before = None
        if self.held is not None and g.stamp_ns > self.held.stamp_ns:
            before = self._release()
        return before, self._restamp(g)

    def odometry(self, o: RobotOdometry) -> list[RobotOdometry]:
        """The odometry to take now, in order: the held one if this one is newer (the gyro
        is silent), then this one unless it is held for its gyro sample."""
        h = self.held
        out: list[RobotOdometry] = []
        last = h.stamp_ns if h is not None else self._released_ns
        if last is not None and o.stamp_ns < last:
            if self._set_back.older(o.stamp_ns, last) != "confirmed":
                self.dropped += 1  # rule 4 (one more than a second back waits in the gate)
                return out
            self._take(self._release(), out)  # the clock was set back: the old line first
            self._released_ns = None
        else:
            self._set_back.newer()
            if h is not None:
                if o.stamp_ns == h.stamp_ns:
                    self.dropped += 1  # rule 3: the earlier one of a burst, replaced by this
                    self.held = o
                    return out
                self._take(self._release(), out)
        last = self._gyro_read_ns
        wait = (
            last is not None
            and o.stamp_ns >= last + self.period_ns  # the gyro's next sample is due
            and o.stamp_ns - last <= self.patience_ns  # and the gyro is not silent
        )
        self.held = o
        if wait:
            self.waited += 1
        else:
            self._take(self._release(), out)
        return out

    @staticmethod
    def _take(o: RobotOdometry | None, out: list[RobotOdometry]) -> None:
        if o is not None:
            out.append(o)

    def _release(self) -> RobotOdometry | None:
        h, self.held = self.held, None
        if h is None:
            return None
        if self._released_ns is not None and h.stamp_ns <= self._released_ns:
            self.dropped += 1  # rule 4
            return None
        self._released_ns = h.stamp_ns
        return h

    def _restamp(self, g: GyroSample) -> GyroSample:
        last = self._gyro_ns
        if last is not None and g.stamp_ns < last + self.spacing_ns:
            if set_back(g.stamp_ns, last):
                self._gyro_ns = g.stamp_ns  # the clock was set back: follow it
                return g
            g = GyroSample(last + self.spacing_ns, g.rate_radps, g.angle_rad, g.angle_wrapped_rad)
        self._gyro_ns = g.stamp_ns
        return g
