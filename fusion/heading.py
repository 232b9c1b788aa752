"""Encoder + gyro heading Kalman filter (ir-grid-mapping.txt §2, eq. 1-4), with a heading
variance that holds on real data.

Between two odometry messages the encoders give the heading change e = dtheta_enc and the
distance d; the gyro gives its own change g over the same interval. The paper's eq. (4)
puts the errors of one step at (alpha d)^2 + (beta e)^2 (encoders) and (gamma g)^2
(gyro), alpha = 3 deg/m, beta = 0.1, gamma = 0.02, initial sigma 0.1 deg.

Read per step, eq. (4) makes the variance depend on the step rate (ten steps of 0.1 m
give a tenth of the variance of one step of 1 m), and it treats what is systematic as
white: a wheel-diameter mismatch turns the robot by the same angle every metre, a gyro
scale error by the same fraction of every turn. On the Intel log the encoders drift about
3 deg/m for hundreds of metres while eq. (4) claimed 18 deg in the end. Here
(``model="increment"``, the default):

- **Random growth per distance and per turn, independent of the step rate**: the
  encoders' step variance is alpha^2 |d| + beta^2 |e| (alpha in rad per sqrt(m): the
  sigma after 1 m; beta per sqrt(rad)), the gyro's gamma^2 |g| + arw^2 dt +
  (bias_sigma dt)^2. Sums of steps give the same variance at any rate.
- **Systematic terms as states**: c_d, the encoders' heading error per metre
  (wheel-diameter mismatch; prior sigma ``encoder_bias_sigma_rad_per_m``, mean the
  calibrated ``encoder_bias_rad_per_m``), c_t, their error per radian turned (track
  width; ``track_scale_sigma``), and c_g, the gyro's scale error (``gyro_scale_sigma``).
  The state is x = (theta, c_d, c_t, c_g); the encoders predict
      theta' = theta + e + c_d d + c_t e                                   (eq. 1)
  and the gyro measures the step's change, g = (theta' - theta)(1 + c_g) + v (eq. 3):
  the filter clones theta at the start of the step (stochastic cloning) and updates the
  joint state with H = (-(1 + c_g), 1 + c_g, 0, 0, theta' - theta) (eq. 2-3). The gyro
  thus learns c_d and c_t - c_g (``learn_systematic``; otherwise they are "consider"
  states: their uncertainty counts, their estimates stay), and an encoder-only run
  keeps their full prior: its sigma grows with the distance, not its square root, and
  covers the real drift instead of claiming a few degrees.

With every systematic sigma at 0 this is the increment filter of the paper's §2 (the
gyro measures a change, so the heading uncertainty "cannot shrink", fig. 3c): gain
K = sw^2 / (sw^2 + sg^2), theta' = theta + e + K (g - e), sigma'^2 = sigma^2 + sw^2 (1 - K).
``model="paper"`` keeps eq. (1)-(4) read literally, per step (the gyro's heading taken as
an absolute measurement: over-confident), for comparison.

:attr:`HeadingFilter.lost` says when 3 sigma exceeds 90 deg: the heading is gone, and a
map drawn with it cannot be trusted (counted as ``lost_steps``).

The gyro's bias is learnt while the robot stands still (odometry not moving for
``bias_min_rest_s``), averaged over up to ``bias_window_s`` of rest
(fusion.increments.RestBias), and removed.

Which gyro change goes with which odometry step is decided by the alignment front end
(fusion.alignment), which drives this filter's predict/update: a step the gyro has not
caught up with (late or bunched messages after a host stall) is predicted on the encoders
and corrected retroactively once the gyro covers it (:meth:`HeadingFilter.correct_deferred`:
the clone is taken at the start of the deferred interval); a step whose two changes
disagree beyond the chi-square gate ``gyro_gate_probability`` is postponed once and fused
over the longer interval, and if they still disagree the encoders are taken as the
outlier (the gyro cannot jump, a bad SIP can). No gyro rotation is dropped while the
gyro runs, so no burst leaves a permanent offset.

Position (as in the paper): x, y integrate the encoder distance along the fused heading
(midpoint of the step).

Message-level API (what the pipeline calls):
    f = HeadingFilter(HeadingParams(), initial=Pose2D(...), arrival=ArrivalOrder(rate_hz))
    f.feed(msg) -> HeadingEstimate | None   # the estimate whenever an odometry step ran
    f.feed_odometry(msg) / f.feed_gyro(msg); f.estimate(); f.reset(pose, stamp_ns)
    f.counters() -> dict[str, int | float]  (for diagnostics)
``arrival`` (fusion.arrival): messages in arrival order as the drivers stamp them, put in
stamp order first; without it the stamps are trusted and a gyro sample never runs a step.
Array-level API: ``f.step(dd, dtheta_enc, dtheta_gyro | None, dt_s)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fusion.alignment import Advance, AlignedInput, Deferred, GyroOdometryAlignment
from fusion.arrival import ArrivalOrder
from fusion.ekf_update import chi2_gate
from fusion.heading_params import DEG, HeadingParams
from fusion.increments import OdometryStep
from msgs import HeadingEstimate, Pose2D, wrap_angle

LOST_3SIGMA_RAD = math.pi / 2
# State indices: the clone of theta at the start of the current interval, theta, c_d, c_t,
# c_g, and the gyro's residual bias b (rad/s).
A, TH, CD, CT, CG, B = range(6)
N = 6
__all__ = ["DEG", "HeadingCounters", "HeadingFilter", "HeadingParams"]


@dataclass
class HeadingCounters:
    steps: int = 0
    steps_fused: int = 0
    steps_encoder_only: int = 0
    gyro_merges: int = 0
    odometry_heading_rejected: int = 0
    bad_input: int = 0
    lost_steps: int = 0


class HeadingFilter(AlignedInput):
    """Heading Kalman filter of ir-grid-mapping eq. 1-4 (see module docstring)."""

    def __init__(
        self,
        params: HeadingParams | None = None,
        initial: Pose2D | None = None,
        arrival: ArrivalOrder | None = None,
    ):
        self.params = params or HeadingParams()
        self._align = GyroOdometryAlignment(self.params, arrival)
        g = self.params.gyro_gate_probability
        self.heading_gate = chi2_gate(g, 1)
        self._count = HeadingCounters()
        self.reset(initial or Pose2D(), 0)

    # -- state -----------------------------------------------------------------------
    def reset(
        self, pose: Pose2D | None = None, stamp_ns: int = 0, variance_rad2: float | None = None
    ) -> None:
        """Restart at ``pose`` (default: the origin); the next odometry is a new baseline.
        The systematic terms start again from their priors."""
        p = self.params
        pose = pose or Pose2D()
        self.x, self.y = float(pose.x), float(pose.y)
        self.theta = wrap_angle(float(pose.theta))
        s0 = p.initial_sigma_rad
        v0 = float(s0 * s0 if variance_rad2 is None else variance_rad2)
        self.c = np.array([p.encoder_bias_rad_per_m, 0.0, 0.0, 0.0])  # c_d, c_t, c_g, b
        prior = [p.encoder_bias_sigma_rad_per_m**2, p.track_scale_sigma**2,
                 p.gyro_scale_sigma**2, p.gyro_bias_sigma_radps**2]  # fmt: skip
        if p.model == "paper":
            prior = [0.0, 0.0, 0.0, 0.0]
        self.P = np.diag([v0, v0, *prior])
        self.P[A, TH] = self.P[TH, A] = v0
        self._anchor = self.theta
        self._span_s = 0.0
        self.stamp_ns = int(stamp_ns)
        self._align.reset()

    @property
    def variance(self) -> float:
        """Variance of the heading (rad^2), systematic terms included."""
        return float(self.P[TH, TH])

    @property
    def lost(self) -> bool:
        """3 sigma beyond 90 deg: the filter's own verdict that the heading is gone."""
        return 9.0 * self.variance >= LOST_3SIGMA_RAD**2

    @property
    def systematic(self) -> dict[str, float]:
        """The systematic terms' estimates and sigmas (c_d rad/m, c_t, c_g, b rad/s)."""
        sd = np.sqrt(np.maximum(np.diag(self.P)[CD:], 0.0))
        return {
            "encoder_bias_rad_per_m": float(self.c[0]),
            "encoder_bias_sigma_rad_per_m": float(sd[0]),
            "track_scale": float(self.c[1]),
            "track_scale_sigma": float(sd[1]),
            "gyro_scale": float(self.c[2]),
            "gyro_scale_sigma": float(sd[2]),
            "gyro_bias_radps": float(self.c[3]),
            "gyro_bias_sigma_radps": float(sd[3]),
        }

    def estimate(self) -> HeadingEstimate:
        return HeadingEstimate(
            self.stamp_ns, self.theta, self.variance, Pose2D(self.x, self.y, self.theta)
        )

    # -- the Kalman filter on (clone, theta, c_d, c_t, c_g) ------------------------------
    def _clone(self) -> None:
        """Start an interval: the clone takes theta's value and covariance."""
        P = self.P
        P[A, :] = P[TH, :]
        P[:, A] = P[:, TH]
        self._anchor = self.theta
        self._span_s = 0.0

    def _predict(self, dd: float, e: float, dt_s: float) -> float:
        """Eq. (1) on the encoders' step; returns the heading change applied."""
        cd, ct = self.c[0], self.c[1]
        u = e + cd * dd + ct * e
        F = np.eye(N)
        F[TH, CD], F[TH, CT] = dd, e
        self.P = F @ self.P @ F.T
        self.P[TH, TH] += self._encoder_noise(dd, e)
        self.P[B, B] += self.params.gyro_bias_walk_radps_per_sqrt_s**2 * dt_s
        self._span_s += dt_s
        self.theta = wrap_angle(self.theta + u)
        return u

    def _update(self, g: float, r: float, covered_s: float, take_gyro: bool = False) -> float:
        """Eq. (2)-(3): the gyro's change ``g`` (variance ``r``) over the ``covered_s``
        seconds since the clone, g = (theta - clone)(1 + c_g) + b T; ``take_gyro``: the
        encoders are the outlier, theta = clone + (g - b T) / (1 + c_g). Returns the
        heading correction."""
        P = self.P
        span = wrap_angle(self.theta - self._anchor)
        sc = 1.0 + self.c[2]
        T = max(covered_s, 0.0)
        if take_gyro:
            delta = wrap_angle(self._anchor + (g - self.c[3] * T) / sc - self.theta)
            P[TH, :] = P[A, :]
            P[:, TH] = P[:, A]
            P[TH, TH] = P[A, A] + r + (g * g) * P[CG, CG] + T * T * P[B, B]
            self.theta = wrap_angle(self.theta + delta)
            return delta
        H = np.zeros(N)
        H[A], H[TH], H[CG], H[B] = -sc, sc, span, T
        nu = g - span * sc - self.c[3] * T
        PH = P @ H
        S = float(H @ PH) + r
        K = PH / S
        if not self.params.learn_systematic:
            K[CD:B] = 0.0  # consider states: their uncertainty counts, they are not estimated
        IKH = np.eye(N) - np.outer(K, H)
        self.P = IKH @ P @ IKH.T + r * np.outer(K, K)
        self.P = 0.5 * (self.P + self.P.T)
        self.c = self.c + K[CD:] * nu
        delta = float(K[TH] * nu)
        self.theta = wrap_angle(self.theta + delta)
        return delta

    def _encoder_noise(self, dd: float, e: float) -> float:
        p = self.params
        if p.model == "paper":
            return (p.alpha_rad_per_m * dd) ** 2 + (p.beta * e) ** 2 + p.variance_floor_rad2
        return p.alpha_rad_per_m**2 * abs(dd) + p.beta**2 * abs(e) + p.variance_floor_rad2

    # -- array-level -----------------------------------------------------------------
    def step(self, dd: float, dtheta_enc: float, dtheta_gyro: float | None, dt_s: float) -> None:
        """One filter step: distance dd (m), encoder and gyro heading changes (rad)."""
        if not (math.isfinite(dd) and math.isfinite(dtheta_enc)):
            self._count.bad_input += 1
            return
        if dtheta_gyro is not None and not math.isfinite(dtheta_gyro):
            self._count.bad_input += 1
            dtheta_gyro = None
        dt_s = max(0.0, dt_s)
        th0 = self.theta
        if dtheta_gyro is None:
            self._predict(dd, dtheta_enc, dt_s)
            self._count.steps_encoder_only += 1
        elif self.params.model == "paper":
            self._paper_step(dd, dtheta_enc, dtheta_gyro, dt_s)
            self._count.steps_fused += 1
        else:
            self._clone()
            self._predict(dd, dtheta_enc, dt_s)
            r = self.gyro_variance(dtheta_gyro, dt_s, systematic=False)
            self._update(dtheta_gyro, r, dt_s)
            self._count.steps_fused += 1
        u = wrap_angle(self.theta - th0)
        mid = th0 + 0.5 * u
        self.x += dd * math.cos(mid)
        self.y += dd * math.sin(mid)
        self._count.steps += 1
        if self.lost:
            self._count.lost_steps += 1

    def _paper_step(self, dd: float, e: float, g: float, dt_s: float) -> None:
        """Eq. (1)-(3) read literally: the gyro's heading as an absolute measurement."""
        sw2 = self._encoder_noise(dd, e)
        sg2 = self.gyro_variance(g, dt_s, systematic=False)
        prior = self.variance + sw2  # eq. (1)
        k = prior / (prior + sg2)  # eq. (2)
        self.theta = wrap_angle(self.theta + e + k * (g - e))  # eq. (3), z = theta + dg
        self.P[TH, TH] = self.P[A, A] = self.P[A, TH] = self.P[TH, A] = prior * (1.0 - k)

    def gyro_variance(self, dtheta_gyro: float, dt_s: float, systematic: bool = True) -> float:
        """The gyro's variance of a change (eq. 4 per turn, or per step with model
        "paper"), plus its angle random walk, plus (``systematic``) the share of the scale
        error and of the residual bias (model "paper": the bias as white per step)."""
        p = self.params
        g = abs(dtheta_gyro)
        turn = (p.gamma * g) ** 2 if p.model == "paper" else p.gamma**2 * g
        var = turn + p.gyro_arw_rad_per_sqrt_s**2 * dt_s
        if p.model == "paper":
            var += (p.gyro_bias_sigma_radps * dt_s) ** 2
        elif systematic:
            var += g * g * float(self.P[CG, CG]) + dt_s * dt_s * float(self.P[B, B])
        return var + p.variance_floor_rad2

    # -- what the alignment front end calls (fusion.alignment.AlignedFilter) ----------
    def encoder_variance(self, step: OdometryStep) -> float:
        """The encoders' step variance: random, plus the systematic terms' share."""
        dd, e = step.ds_m, step.dtheta_rad
        h = np.array([dd, e])
        sys = float(h @ self.P[CD : CT + 1, CD : CT + 1] @ h)
        return self._encoder_noise(dd, e) + sys

    def position(self) -> tuple[float, float]:
        return self.x, self.y

    def predict_step(self, step: OdometryStep, dtheta_gyro: float | None, covered_s: float) -> None:
        """One step of eq. (1)-(4); the gyro's variance is taken over the step's dt."""
        if dtheta_gyro is None:
            d = self._align.deferred
            if d is not None and d.steps == 1:
                self._clone()  # a deferred interval starts: the gyro will cover it later
        self.step(step.ds_m, step.dtheta_rad, dtheta_gyro, step.dt_s)

    def correct_deferred(self, d: Deferred, dtheta_gyro: float, covered_s: float) -> None:
        """Fuse the gyro's change over a deferred interval, retroactively.

        The deferred steps were predicted on the encoders from the clone taken at the
        interval's start; the gyro's change G over the interval is the measurement of
        eq. (2)-(3) (beyond the gate while moving, the encoders are the outlier and G is
        taken). The position driven meanwhile is rotated about its start by half the
        correction (the heading error grew along the interval).
        """
        r = self.gyro_variance(dtheta_gyro, covered_s, systematic=False)
        nu = dtheta_gyro - d.dtheta_enc
        gate = d.moving and nu * nu / (d.var_enc + r) > self.heading_gate
        if gate:
            self._count.odometry_heading_rejected += 1
        if self.params.model == "paper":
            delta = nu * d.var_enc / (d.var_enc + r) if not gate else nu
            self.P[TH, TH] = max(self.variance - d.var_enc * delta / nu if nu else self.variance,
                                 self.params.variance_floor_rad2)  # fmt: skip
            self.theta = wrap_angle(self.theta + delta)
        else:
            delta = self._update(dtheta_gyro, r, covered_s, take_gyro=gate)
        self.x, self.y = d.rotate(self.x, self.y, 0.5 * delta)
        self._count.steps_fused += d.steps
        self._count.steps_encoder_only -= d.steps
        self._count.gyro_merges += 1

    def turn(self, dtheta_gyro: float, covered_s: float) -> None:
        """Turn by the gyro's change alone (an interval the odometry lost)."""
        sc = 1.0 + self.c[2]
        T = max(covered_s, 0.0)
        F = np.eye(N)
        F[TH, CG] = -(dtheta_gyro - self.c[3] * T) / (sc * sc)
        F[TH, B] = -T / sc
        self.P = F @ self.P @ F.T
        self.P[TH, TH] += self.gyro_variance(dtheta_gyro, covered_s, systematic=False)
        self.P[B, B] += self.params.gyro_bias_walk_radps_per_sqrt_s**2 * T
        self.theta = wrap_angle(self.theta + (dtheta_gyro - self.c[3] * T) / sc)

    # -- message-level ---------------------------------------------------------------
    def _advanced(self, a: Advance | None) -> HeadingEstimate | None:
        if a is None:
            return None
        self.stamp_ns = a.stamp_ns
        return self.estimate()

    def counters(self) -> dict[str, int | float | bool]:
        c, a = self._count, self._align
        return {
            "odometry": a.odo.messages,
            "gyro": a.gyro.messages,
            "steps": c.steps,
            "steps_fused": c.steps_fused,
            "steps_encoder_only": c.steps_encoder_only,
            "gyro_timeouts": a.gyro_timeouts,
            "gyro_stale": a.gyro_stale,
            "gyro_misaligned": a.misaligned,
            "gyro_merges": c.gyro_merges,
            "gyro_postponed": a.postponed,
            "odometry_heading_rejected": c.odometry_heading_rejected,
            "gyro_deferred_steps": a.deferrals,
            "bad_input": c.bad_input,
            "odometry_out_of_order": a.odo.out_of_order,
            "odometry_jumps": a.odo.jumps,
            "gyro_out_of_order": a.gyro.out_of_order,
            "gyro_discontinuities": a.gyro.discontinuities,
            "gyro_bias_radps": a.bias.bias_radps,
            "odometry_dropped": a.dropped,
            "gyro_late": a.late,
            "heading_lost": self.lost,
            "lost_steps": c.lost_steps,
            "encoder_bias_rad_per_m": float(self.c[0]),
        }
