"""Encoder + gyro heading Kalman filter (ir-grid-mapping.txt §2, eq. 1-4).

The heading theta is a 1-D state. Between two odometry messages the encoders give the
heading change u = dtheta_enc and the distance dd; the gyro gives its own heading change
dtheta_gyro over the same interval. Eq. (4) models their errors as
    sigma_w^2    = (alpha dd)^2 + (beta dtheta_enc)^2          (encoder, the input)
    sigma_gyro^2 = (gamma dtheta_gyro)^2                         (gyro, the observation)
with alpha = 3 deg/m, beta = 0.1, gamma = 0.02 and an initial sigma of 0.1 deg.

Eq. (1)-(3) read literally (prediction theta^- = theta + u, sigma^- = sigma^2 + sigma_w^2,
gain K = sigma^- / (sigma^- + sigma_gyro^2), observation z = the gyro's heading) treat the
gyro's heading as an absolute measurement with a small variance, so sigma^2 collapses to
about sigma_gyro^2 after every step. But the gyro measures a *change* (the paper says so
under eq. 3, and that the heading uncertainty therefore "cannot shrink", fig. 3c): its
heading is z = theta_t + dtheta_gyro, whose error contains theta_t's own error. The
innovation z - theta^- = dtheta_gyro - u then does not depend on theta_t at all, and the
Kalman filter that accounts for that correlation (``model="increment"``, the default) is

    K         = sigma_w^2 / (sigma_w^2 + sigma_gyro^2)                  (eq. 2, on the step)
    theta'    = theta + u + K (dtheta_gyro - u)                          (eq. 1 + 3)
    sigma'^2  = sigma^2 + sigma_w^2 (1 - K)                              (eq. 1 + 3)

i.e. the two measurements of the step are fused and the heading variance grows by the
fused step's variance. ``model="paper"`` runs eq. (1)-(3) literally, for comparison (it is
over-confident: its NEES is far above 1 on simulated runs). Without a gyro sample in the
step (gyro absent or timed out) only the prediction runs (encoder only).

Eq. (4) gives a zero gyro variance when the robot does not turn, so the gyro's white
noise (angle random walk) and its residual bias can be added, each defaulting to 0 to
keep the paper's model: sigma_gyro^2 += arw^2 dt + (bias_sigma dt)^2. The gyro's bias is
learnt while the robot stands still (odometry not moving for ``bias_min_rest_s``),
averaged over up to ``bias_window_s`` of rest (fusion.increments.RestBias), and removed.

Which gyro change goes with which odometry step is decided by the alignment front end
(fusion.alignment), which drives this filter's predict/update: a step the gyro has not
caught up with (late or bunched messages after a host stall) is predicted on the encoders
and corrected retroactively once the gyro covers it (:meth:`HeadingFilter.correct_deferred`:
eq. 2-3 on the summed interval); a step whose two changes disagree beyond the chi-square
gate ``gyro_gate_probability`` is postponed once and fused over the longer interval, and
if they still disagree the encoders are taken as the outlier (the gyro cannot jump, a bad
SIP can). No gyro rotation is dropped while the gyro runs, so no burst leaves a permanent
offset.

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
from typing import Literal

from scipy.stats import chi2

from fusion.alignment import Advance, AlignedInput, Deferred, GyroOdometryAlignment
from fusion.arrival import ArrivalOrder
from fusion.increments import OdometryStep
from msgs import HeadingEstimate, Pose2D, wrap_angle

DEG = math.pi / 180.0


@dataclass(frozen=True)
class HeadingParams:
    """Parameters of the heading filter (defaults: the paper's, eq. 4)."""

    alpha_rad_per_m: float = 3.0 * DEG
    beta: float = 0.1
    gamma: float = 0.02
    initial_sigma_rad: float = 0.1 * DEG
    model: Literal["increment", "paper"] = "increment"
    # Extras beyond eq. (4), 0 = the paper's model:
    gyro_arw_rad_per_sqrt_s: float = 0.0
    gyro_bias_sigma_radps: float = 0.0
    # Gyro handling:
    gyro_timeout_s: float = 0.5
    gyro_max_lag_s: float = 0.05
    gyro_max_defer_s: float = 2.0
    gyro_gate_probability: float | None = 0.9999
    learn_bias_at_rest: bool = True
    bias_window_s: float = 30.0
    bias_min_rest_s: float = 0.5
    variance_floor_rad2: float = 1e-18

    def __post_init__(self) -> None:
        for name in ("alpha_rad_per_m", "beta", "gamma", "initial_sigma_rad",
                     "gyro_arw_rad_per_sqrt_s", "gyro_bias_sigma_radps", "gyro_timeout_s",
                     "gyro_max_lag_s", "gyro_max_defer_s", "bias_window_s", "bias_min_rest_s"):  # fmt: skip
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"HeadingParams.{name} must be finite and >= 0, got {v!r}")
        g = self.gyro_gate_probability
        if g is not None and not 0.0 < g < 1.0:
            raise ValueError(f"HeadingParams.gyro_gate_probability must be in (0, 1), got {g!r}")
        if self.model not in ("increment", "paper"):
            raise ValueError(
                f"HeadingParams.model must be 'increment' or 'paper', got {self.model!r}"
            )


@dataclass
class HeadingCounters:
    steps: int = 0
    steps_fused: int = 0
    steps_encoder_only: int = 0
    gyro_merges: int = 0
    odometry_heading_rejected: int = 0
    bad_input: int = 0


class HeadingFilter(AlignedInput):
    """1-D heading Kalman filter of ir-grid-mapping eq. 1-4 (see module docstring)."""

    def __init__(
        self,
        params: HeadingParams | None = None,
        initial: Pose2D | None = None,
        arrival: ArrivalOrder | None = None,
    ):
        self.params = params or HeadingParams()
        self._align = GyroOdometryAlignment(self.params, arrival)
        g = self.params.gyro_gate_probability
        self.heading_gate = math.inf if g is None else float(chi2.ppf(g, 1))
        self._count = HeadingCounters()
        self.reset(initial or Pose2D(), 0)

    # -- state -----------------------------------------------------------------------
    def reset(
        self, pose: Pose2D | None = None, stamp_ns: int = 0, variance_rad2: float | None = None
    ) -> None:
        """Restart at ``pose`` (default: the origin); the next odometry is a new baseline."""
        pose = pose or Pose2D()
        self.x, self.y = float(pose.x), float(pose.y)
        self.theta = wrap_angle(float(pose.theta))
        s0 = self.params.initial_sigma_rad
        self.variance = float(s0 * s0 if variance_rad2 is None else variance_rad2)
        self.stamp_ns = int(stamp_ns)
        self._align.reset()

    def estimate(self) -> HeadingEstimate:
        return HeadingEstimate(
            self.stamp_ns, self.theta, self.variance, Pose2D(self.x, self.y, self.theta)
        )

    # -- array-level -----------------------------------------------------------------
    def step(self, dd: float, dtheta_enc: float, dtheta_gyro: float | None, dt_s: float) -> None:
        """One filter step: distance dd (m), encoder and gyro heading changes (rad)."""
        p = self.params
        if not (math.isfinite(dd) and math.isfinite(dtheta_enc)):
            self._count.bad_input += 1
            return
        if dtheta_gyro is not None and not math.isfinite(dtheta_gyro):
            self._count.bad_input += 1
            dtheta_gyro = None
        dt_s = max(0.0, dt_s)
        sw2 = self._encoder_var(dd, dtheta_enc)  # eq. (4)
        if dtheta_gyro is None:
            u = dtheta_enc
            self.variance += sw2
            self._count.steps_encoder_only += 1
        else:
            sg2 = self.gyro_variance(dtheta_gyro, dt_s)
            if p.model == "paper":
                prior = self.variance + sw2  # eq. (1)
                k = prior / (prior + sg2)  # eq. (2)
                u = dtheta_enc + k * (dtheta_gyro - dtheta_enc)  # eq. (3), z = theta + dg
                self.variance = prior * (1.0 - k)  # eq. (3)
            else:
                k = sw2 / (sw2 + sg2)
                u = dtheta_enc + k * (dtheta_gyro - dtheta_enc)
                self.variance += sw2 * (1.0 - k)
            self._count.steps_fused += 1
        mid = self.theta + 0.5 * u
        self.x += dd * math.cos(mid)
        self.y += dd * math.sin(mid)
        self.theta = wrap_angle(self.theta + u)
        self._count.steps += 1

    def _encoder_var(self, dd: float, dtheta_enc: float) -> float:
        p = self.params
        return (p.alpha_rad_per_m * dd) ** 2 + (p.beta * dtheta_enc) ** 2 + p.variance_floor_rad2

    def gyro_variance(self, dtheta_gyro: float, dt_s: float) -> float:
        """sigma_gyro^2 of eq. (4), plus the angle random walk and the residual bias."""
        p = self.params
        return (
            (p.gamma * dtheta_gyro) ** 2
            + p.gyro_arw_rad_per_sqrt_s**2 * dt_s
            + (p.gyro_bias_sigma_radps * dt_s) ** 2
            + p.variance_floor_rad2
        )

    # -- what the alignment front end calls (fusion.alignment.AlignedFilter) ----------
    def encoder_variance(self, step: OdometryStep) -> float:
        return self._encoder_var(step.ds_m, step.dtheta_rad)

    def position(self) -> tuple[float, float]:
        return self.x, self.y

    def predict_step(self, step: OdometryStep, dtheta_gyro: float | None, covered_s: float) -> None:
        """One step of eq. (1)-(4); the gyro's variance is taken over the step's dt."""
        self.step(step.ds_m, step.dtheta_rad, dtheta_gyro, step.dt_s)

    def correct_deferred(self, d: Deferred, dtheta_gyro: float, covered_s: float) -> None:
        """Fuse the gyro's change over a deferred interval, retroactively (increment model).

        The deferred steps were predicted on the encoders: theta moved by their sum E and
        the variance grew by their variance sum Sw. The gyro's change G over the same
        interval corrects theta by K (G - E), K = Sw / (Sw + Sg) (eq. 2-3 on the
        interval; K = 1 beyond the gate while moving: the encoders are the outlier), and
        removes K Sw of the variance; the position driven meanwhile is rotated about its
        start by half the correction (the heading error grew along the interval).
        """
        sw2, sg2 = d.var_enc, self.gyro_variance(dtheta_gyro, covered_s)
        nu = dtheta_gyro - d.dtheta_enc
        k = sw2 / (sw2 + sg2)
        if d.moving and nu * nu / (sw2 + sg2) > self.heading_gate:
            k = 1.0
        if k == 1.0:
            self._count.odometry_heading_rejected += 1
        delta = k * nu
        self.variance = max(self.variance - k * sw2, self.params.variance_floor_rad2)
        self.x, self.y = d.rotate(self.x, self.y, 0.5 * delta)
        self.theta = wrap_angle(self.theta + delta)
        self._count.steps_fused += d.steps
        self._count.steps_encoder_only -= d.steps
        self._count.gyro_merges += 1

    def turn(self, dtheta_gyro: float, covered_s: float) -> None:
        self.theta = wrap_angle(self.theta + dtheta_gyro)
        self.variance += self.gyro_variance(dtheta_gyro, covered_s)

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
        }
