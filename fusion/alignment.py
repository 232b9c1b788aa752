"""The gyro/odometry alignment front end: it hands the fusion filters matched intervals.

Both fusion filters fuse the gyro's heading change with the encoders' over the *same*
interval between two odometry messages (ir-grid-mapping eq. 1-4; ekf-vs-cp eq. 1-4 with
the gyro as an increment). :class:`GyroOdometryAlignment` takes the gyro samples and the
odometry messages and, at every odometry message, tells its filter (the
:class:`AlignedFilter` protocol: the filter's noise model and its predict/update steps)
what to do with that interval: predict with or without the gyro's change, correct
deferred steps retroactively, or turn by the gyro alone. The filters keep only their
predict/update; which gyro change goes with which odometry step is decided here alone.

With an :class:`fusion.arrival.ArrivalOrder` (the pipeline's case: messages in arrival
order as the stream drivers stamp them, bursts sharing one stamp) the messages are first
put in stamp order (gyro restamped, odometry held only while the gyro sample covering it
is due, bursts and stale odometry dropped: see fusion.arrival). Without one the stamps
are trusted (offline or simulated messages) and every odometry message is taken when it
comes.

Then, per odometry step (fusion.increments: odometry poses -> steps, gyro angles ->
changes that telescope), the decisions (:data:`Decision`):

1. *No gyro rotation is lost or counted twice while the gyro runs*: a gyro change is
   taken only when it is used, so the used changes sum to the gyro's total rotation.
2. ``"fuse"``: the gyro has caught up with the step (its newest sample no more than
   ``gyro_max_lag_s`` older than the step's end): the filter fuses both changes.
3. ``"deferred"``: it has not; the filter predicts on the encoders and the step joins a
   deferred interval (:class:`Deferred`). ``"merged"``: the gyro has caught up with a
   deferred interval; its change over the whole interval is fused with the encoders'
   over the same interval, which corrects the heading retroactively.
4. ``"timeout"``: deferred for longer than ``gyro_max_defer_s``; the gyro is given up for
   that interval (the encoder-only prediction stands; counted ``misaligned``) and
   re-baselines at its next sample. ``"unchained"``: no gyro chain yet (or after a
   timeout): encoder only; the chain starts at the end of a step the gyro has caught up
   with.
5. ``"postponed"``: on a fresh step the two changes disagree beyond the filter's
   chi-square gate while the robot moves. If the stamps misled the alignment (a burst),
   the disagreement vanishes over a longer interval: the step is deferred and its gyro
   change carried to the next one (the filter's gate on the merge then decides, taking
   the encoders as the outlier beyond it: the gyro cannot jump, a bad SIP can).
6. At an odometry baseline (first message, or a jump): a deferred interval is corrected
   with the gyro's change since; if the odometry lost an interval the gyro covered, the
   gyro alone turns the heading over it.

Every gyro change handed to the filter has the bias learnt at rest removed
(fusion.increments.RestBias, learnt on the ``"fuse"`` steps). The gyro is flagged stale
when silent for longer than ``gyro_timeout_s`` (transitions counted ``gyro_timeouts``).

One instance per filter, not one shared: decisions 3-5 depend on the filter (rule 5's
gate is its own noise model, a deferred interval holds its position), so two filters
cannot share that state; the arrival-order stage depends on the input sequence alone, so
each filter's copy does the same thing, and each service stays switchable on its own.

Pure: no threads or clocks, time is the message stamps (integer ns); deterministic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal, Protocol

from fusion.arrival import ArrivalOrder
from fusion.increments import NS, GyroDelta, GyroDeltas, OdometryDeltas, OdometryStep, RestBias
from msgs import GyroSample, RobotOdometry
from msgs.stamps import set_back

Decision = Literal["fuse", "merged", "deferred", "postponed", "timeout", "unchained"]


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

    def rotate(self, x: float, y: float, angle: float) -> tuple[float, float]:
        """The point (x, y) rotated by ``angle`` about the interval's start position."""
        c, s = math.cos(angle), math.sin(angle)
        ex, ey = x - self.x0, y - self.y0
        return self.x0 + c * ex - s * ey, self.y0 + s * ex + c * ey


@dataclass(frozen=True, slots=True)
class Advance:
    """An odometry message the filter took: a step ran, or (``step`` None) a new baseline."""

    stamp_ns: int
    step: OdometryStep | None


class GyroHandling(Protocol):
    """The gyro handling parameters (HeadingParams and PoseEkfParams both have them)."""

    @property
    def gyro_max_lag_s(self) -> float: ...
    @property
    def gyro_max_defer_s(self) -> float: ...
    @property
    def gyro_timeout_s(self) -> float: ...
    @property
    def learn_bias_at_rest(self) -> bool: ...
    @property
    def bias_window_s(self) -> float: ...
    @property
    def bias_min_rest_s(self) -> float: ...


class AlignedFilter(Protocol):
    """What the front end needs of a filter. Gyro changes (rad) come bias-removed, with
    the time they cover (s)."""

    @property
    def heading_gate(self) -> float:
        """Chi-square gate (1 dof) on a step's gyro-minus-encoder innovation."""
        ...

    def encoder_variance(self, step: OdometryStep) -> float:
        """Variance (rad^2) of the encoders' heading change over the step."""
        ...

    def gyro_variance(self, dtheta_rad: float, dt_s: float) -> float:
        """Variance (rad^2) of a gyro heading change."""
        ...

    def position(self) -> tuple[float, float]: ...

    def predict_step(self, step: OdometryStep, dtheta_gyro: float | None, covered_s: float) -> None:
        """Predict over the step, fusing the gyro's change if given (else encoder only)."""
        ...

    def correct_deferred(self, d: Deferred, dtheta_gyro: float, covered_s: float) -> None:
        """Fuse the gyro's change over a deferred interval, retroactively."""
        ...

    def turn(self, dtheta_gyro: float, covered_s: float) -> None:
        """Turn by the gyro's change alone (an interval the odometry lost)."""
        ...


class GyroOdometryAlignment:
    """Gyro samples and odometry messages in -> matched intervals to a filter (module doc)."""

    def __init__(self, params: GyroHandling, arrival: ArrivalOrder | None = None) -> None:
        self.max_lag_s = params.gyro_max_lag_s
        self.max_defer_s = params.gyro_max_defer_s
        self.timeout_s = params.gyro_timeout_s
        self.learn_bias = params.learn_bias_at_rest
        self.arrival = arrival
        self.odo = OdometryDeltas()
        self.gyro = GyroDeltas()
        self.bias = RestBias(params.bias_window_s, params.bias_min_rest_s)
        self.silent_s = math.inf
        self.gyro_stale = True
        self.decision: Decision | None = None
        self.deferred: Deferred | None = None
        self.chained = False
        self.deferrals = 0
        self.postponed = 0
        self.misaligned = 0
        self.gyro_timeouts = 0
        self._carry: GyroDelta | None = None

    def reset(self) -> None:
        """Forget the odometry and gyro baselines and any deferred interval (a filter reset).
        The arrival-order stage and the learnt bias describe the devices and are kept."""
        self.odo.reset()
        self.gyro.reset()
        self.deferred = None
        self._carry = None
        self.chained = False

    @property
    def dropped(self) -> int:
        """Odometry messages the arrival-order stage dropped (bursts, stale)."""
        return 0 if self.arrival is None else self.arrival.dropped

    @property
    def late(self) -> int:
        """Gyro samples that came after the odometry they precede was taken (their
        rotation goes into the next step's gyro change)."""
        return 0 if self.arrival is None else self.arrival.late

    # -- messages --------------------------------------------------------------------
    def feed_gyro(self, msg: GyroSample, filt: AlignedFilter) -> Advance | None:
        """Take a gyro sample; first the odometry it releases, if any (arrival order)."""
        if self.arrival is None:
            self.gyro.feed(msg)
            return None
        held, msg = self.arrival.gyro(msg)
        out = None if held is None else self._take(held, filt)
        self.gyro.feed(msg)
        return out

    def feed_odometry(self, msg: RobotOdometry, filt: AlignedFilter) -> Advance | None:
        """Take an odometry message (or, in arrival order, those it releases: the last
        one's step is returned): None if no step ran and no baseline was set (held,
        dropped, not newer)."""
        if self.arrival is None:
            return self._take(msg, filt)
        out = None
        for released in self.arrival.odometry(msg):
            out = self._take(released, filt) or out
        return out

    def _take(self, msg: RobotOdometry, filt: AlignedFilter) -> Advance | None:
        step = self.odo.feed(msg)
        if step is not None:
            self._step(step, filt)
            return Advance(step.t1_ns, step)
        if not self.odo.baselined:
            return None
        d, self.deferred = self.deferred, None
        lost = self._baseline()
        if d is not None and lost is not None:
            filt.correct_deferred(d, self._unbiased(lost), lost.covered_s)
        elif lost is not None:
            filt.turn(self._unbiased(lost), lost.covered_s)
        return Advance(msg.stamp_ns, None)

    # -- intervals -------------------------------------------------------------------
    def _step(self, step: OdometryStep, filt: AlignedFilter) -> None:
        decision, gyro = self._decide(step)
        if self.learn_bias:
            self.bias.observe(step, gyro if decision == "fuse" else None)
        stale = self.silent_s > self.timeout_s
        if stale and not self.gyro_stale:
            self.gyro_timeouts += 1
        self.gyro_stale = stale
        var_enc = filt.encoder_variance(step)
        x0, y0 = filt.position()
        if decision == "fuse" and gyro is not None:
            dg = self._unbiased(gyro)
            nu = dg - step.dtheta_rad
            s = var_enc + filt.gyro_variance(dg, gyro.covered_s)
            if not step.at_rest and nu * nu / s > filt.heading_gate:
                # rule 5: defer the step, carry the gyro's change to the next one
                decision = "postponed"
                self._defer(step, var_enc, x0, y0)
                self._carry = gyro
                self.postponed += 1
                filt.predict_step(step, None, 0.0)
            else:
                filt.predict_step(step, dg, gyro.covered_s)
        else:
            if decision in ("deferred", "merged"):
                self._defer(step, var_enc, x0, y0)
            filt.predict_step(step, None, 0.0)
            if decision == "merged":
                d, self.deferred = self.deferred, None
                if d is not None and gyro is not None:
                    filt.correct_deferred(d, self._unbiased(gyro), gyro.covered_s)
        self.decision = decision

    def _unbiased(self, g: GyroDelta) -> float:
        return g.angle_rad - self.bias.bias_radps * g.covered_s

    def _decide(self, step: OdometryStep) -> tuple[Decision, GyroDelta | None]:
        last = self.gyro.last_stamp_ns
        # No sample yet, or the last from before a clock set back the gyro has not followed
        # (msgs.stamps): silent.
        gone = last is None or set_back(step.t1_ns, last)
        self.silent_s = math.inf if gone else (step.t1_ns - last) * NS
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
                self.misaligned += 1
                return "timeout", None
            self.deferrals += 1
            return "deferred", None
        g = self._with_carry(self.gyro.take())
        if g is None:  # caught up, no new sample: the gyro saw no rotation since its last take
            g = GyroDelta(0.0, 0.0, 0)
        return ("fuse" if self.deferred is None else "merged"), g

    def _with_carry(self, g: GyroDelta | None) -> GyroDelta | None:
        """``g`` plus the gyro change carried from a postponed step (which is consumed)."""
        c, self._carry = self._carry, None
        if c is None or g is None:
            return c if g is None else g
        return GyroDelta(
            c.angle_rad + g.angle_rad, c.covered_s + g.covered_s, c.samples + g.samples
        )

    def _baseline(self) -> GyroDelta | None:
        """At an odometry baseline the gyro starts over too. Returns the gyro's change
        since the last step if the gyro was chained (it covers the interval the odometry
        lost, so the filter keeps it)."""
        g = self._with_carry(self.gyro.take())
        chained = self.chained
        self.chained = self.gyro.last is not None
        return g if chained else None

    def _defer(self, step: OdometryStep, var_enc: float, x: float, y: float) -> None:
        """Add a step to the deferred interval (x, y: the position before it)."""
        d = self.deferred
        if d is None:
            d = self.deferred = Deferred(step.t0_ns, x, y)
        d.steps += 1
        d.dtheta_enc += step.dtheta_rad
        d.var_enc += var_enc
        d.moving = d.moving or not step.at_rest


class AlignedInput:
    """Mixin of a filter fed through a :class:`GyroOdometryAlignment` (``self._align``):
    the message-level ``feed`` calls, each handing the front end's step to the filter's
    ``_advanced`` (which returns the filter's estimate message)."""

    _align: GyroOdometryAlignment

    def _advanced(self, a: Advance | None) -> Any:
        raise NotImplementedError

    @property
    def gyro_bias_radps(self) -> float:
        """The gyro bias learnt while the robot stood still."""
        return self._align.bias.bias_radps

    @property
    def gyro_stale(self) -> bool:
        return self._align.gyro_stale

    def feed(self, msg: object) -> Any:
        """RobotOdometry or GyroSample -> the new estimate if a step ran (a gyro sample: only
        if it released held odometry), else None; other messages go to ``_feed_other``."""
        if isinstance(msg, RobotOdometry):
            return self.feed_odometry(msg)
        if isinstance(msg, GyroSample):
            return self.feed_gyro(msg)
        return self._feed_other(msg)

    def _feed_other(self, msg: object) -> Any:
        raise TypeError(
            f"{type(self).__name__} is fed RobotOdometry or GyroSample, not {type(msg)}"
        )

    def feed_gyro(self, msg: GyroSample) -> Any:
        """Take a gyro sample; an estimate only if it released held odometry (``arrival``)."""
        a = self._align.feed_gyro(msg, self)  # type: ignore[arg-type]
        return None if a is None else self._advanced(a)

    def feed_odometry(self, msg: RobotOdometry) -> Any:
        """Run one step on the motion since the previous odometry; None if no step ran."""
        return self._advanced(self._align.feed_odometry(msg, self))  # type: ignore[arg-type]
