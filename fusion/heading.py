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

Which gyro change goes with which odometry step is decided by fusion.alignment: a step
the gyro has not caught up with (late or bunched messages after a host stall) is
predicted on the encoders and corrected retroactively once the gyro covers it; a step
whose two changes disagree beyond the chi-square gate ``gyro_gate_probability`` is
postponed once and fused over the longer interval, and if they still disagree the
encoders are taken as the outlier (the gyro cannot jump, a bad SIP can). No gyro
rotation is dropped while the gyro runs, so no burst leaves a permanent offset.

Position (as in the paper): x, y integrate the encoder distance along the fused heading
(midpoint of the step).

Message-level API (what the daemon calls):
    f = HeadingFilter(HeadingParams(), initial=Pose2D(...))
    f.feed(msg) -> HeadingEstimate | None   # RobotOdometry -> estimate; GyroSample -> None
    f.feed_odometry(msg) / f.feed_gyro(msg); f.estimate(); f.reset(pose, stamp_ns)
    f.counters() -> dict[str, int | float]  (for diagnostics)
Array-level API: ``f.step(dd, dtheta_enc, dtheta_gyro | None, dt_s)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from scipy.stats import chi2

from fusion.alignment import Deferred, GyroAlignment
from fusion.increments import GyroDelta, GyroDeltas, OdometryDeltas, RestBias
from msgs import GyroSample, HeadingEstimate, Pose2D, RobotOdometry, wrap_angle

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
    odometry: int = 0
    gyro: int = 0
    steps: int = 0
    steps_fused: int = 0
    steps_encoder_only: int = 0
    gyro_timeouts: int = 0
    gyro_misaligned: int = 0
    gyro_merges: int = 0
    odometry_heading_rejected: int = 0
    bad_input: int = 0


class HeadingFilter:
    """1-D heading Kalman filter of ir-grid-mapping eq. 1-4 (see module docstring)."""

    def __init__(self, params: HeadingParams | None = None, initial: Pose2D | None = None):
        self.params = params or HeadingParams()
        self._odo = OdometryDeltas()
        self._gyro = GyroDeltas()
        self._align = GyroAlignment(
            self._gyro, self.params.gyro_max_lag_s, self.params.gyro_max_defer_s
        )
        g = self.params.gyro_gate_probability
        self._gate = math.inf if g is None else float(chi2.ppf(g, 1))
        self._bias = RestBias(self.params.bias_window_s, self.params.bias_min_rest_s)
        self._count = HeadingCounters()
        self.gyro_stale = True
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
        self._odo.reset()
        self._gyro.reset()
        self._align.reset()

    @property
    def gyro_bias_radps(self) -> float:
        return self._bias.bias_radps

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
        sw2 = self._encoder_var(dd, dtheta_enc)
        if dtheta_gyro is None:
            u = dtheta_enc
            self.variance += sw2
            self._count.steps_encoder_only += 1
        else:
            sg2 = self._gyro_var(dtheta_gyro, dt_s)
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

    def _gyro_var(self, dtheta_gyro: float, dt_s: float) -> float:
        p = self.params
        return (
            (p.gamma * dtheta_gyro) ** 2
            + p.gyro_arw_rad_per_sqrt_s**2 * dt_s
            + (p.gyro_bias_sigma_radps * dt_s) ** 2
            + p.variance_floor_rad2
        )

    def _merge(self, d: Deferred, gyro: GyroDelta) -> None:
        """Fuse the gyro's change over a deferred interval, retroactively (increment model).

        The deferred steps were predicted on the encoders: theta moved by their sum E and
        the variance grew by their variance sum Sw. The gyro's change G over the same
        interval corrects theta by K (G - E), K = Sw / (Sw + Sg), and removes K Sw of the
        variance; the position driven meanwhile is rotated about its start by half the
        correction (the heading error grew along the interval).
        """
        dg = gyro.angle_rad - self._bias.bias_radps * gyro.covered_s
        sw2, sg2 = d.var_enc, self._gyro_var(dg, gyro.covered_s)
        nu = dg - d.dtheta_enc
        k = sw2 / (sw2 + sg2)
        if d.moving and nu * nu / (sw2 + sg2) > self._gate:
            k = 1.0
        if k == 1.0:
            self._count.odometry_heading_rejected += 1
        delta = k * nu
        self.variance = max(self.variance - k * sw2, self.params.variance_floor_rad2)
        c, s = math.cos(0.5 * delta), math.sin(0.5 * delta)
        ex, ey = self.x - d.x0, self.y - d.y0
        self.x, self.y = d.x0 + c * ex - s * ey, d.y0 + s * ex + c * ey
        self.theta = wrap_angle(self.theta + delta)
        self._count.steps_fused += d.steps
        self._count.steps_encoder_only -= d.steps
        self._count.gyro_merges += 1

    # -- message-level ---------------------------------------------------------------
    def feed(self, msg: object) -> HeadingEstimate | None:
        """RobotOdometry -> the new estimate; GyroSample -> None; anything else: TypeError."""
        if isinstance(msg, RobotOdometry):
            return self.feed_odometry(msg)
        if isinstance(msg, GyroSample):
            self.feed_gyro(msg)
            return None
        raise TypeError(f"HeadingFilter is fed RobotOdometry or GyroSample, not {type(msg)}")

    def feed_gyro(self, msg: GyroSample) -> None:
        self._count.gyro += 1
        self._gyro.feed(msg)

    def feed_odometry(self, msg: RobotOdometry) -> HeadingEstimate | None:
        """Run one step on the motion since the previous odometry; None if no step ran.

        The gyro's change is fused only over an interval it has caught up with
        (fusion.alignment): steps it lags behind are predicted on the encoders and
        corrected once it catches up.
        """
        self._count.odometry += 1
        step = self._odo.feed(msg)
        if step is None:
            if self._odo.baselined:  # first message (or a re-baseline): start here
                d = self._align.close()
                lost = self._align.baseline()
                if d is not None and lost is not None:
                    self._merge(d, lost)
                elif lost is not None:  # odometry jumped: the gyro alone turns the heading
                    dg = lost.angle_rad - self._bias.bias_radps * lost.covered_s
                    self.theta = wrap_angle(self.theta + dg)
                    self.variance += self._gyro_var(dg, lost.covered_s)
                self.stamp_ns = msg.stamp_ns
                return self.estimate()
            return None
        decision, gyro = self._align.decide(step)
        if self.params.learn_bias_at_rest:
            self._bias.observe(step, gyro if decision == "fuse" else None)
        stale = self._align.silent_s > self.params.gyro_timeout_s
        if stale and not self.gyro_stale:
            self._count.gyro_timeouts += 1
        self.gyro_stale = stale
        if decision == "timeout":
            self._count.gyro_misaligned += 1
        sw2 = self._encoder_var(step.ds_m, step.dtheta_rad)
        if decision == "fuse" and gyro is not None:
            dg = gyro.angle_rad - self._bias.bias_radps * gyro.covered_s
            nu = dg - step.dtheta_rad
            gated = nu * nu / (sw2 + self._gyro_var(dg, gyro.covered_s)) > self._gate
            if gated and not step.at_rest:
                decision = "postponed"
                self._align.postpone(step, gyro, sw2, self.x, self.y)
                self.step(step.ds_m, step.dtheta_rad, None, step.dt_s)
            else:
                self.step(step.ds_m, step.dtheta_rad, dg, step.dt_s)
        else:
            if decision in ("deferred", "merged"):
                self._align.defer(
                    step, self._encoder_var(step.ds_m, step.dtheta_rad), self.x, self.y
                )
            self.step(step.ds_m, step.dtheta_rad, None, step.dt_s)
            if decision == "merged":
                d = self._align.close()
                if d is not None and gyro is not None:
                    self._merge(d, gyro)
        self.stamp_ns = step.t1_ns
        return self.estimate()

    def counters(self) -> dict[str, int | float | bool]:
        c = self._count
        return {
            "odometry": c.odometry,
            "gyro": c.gyro,
            "steps": c.steps,
            "steps_fused": c.steps_fused,
            "steps_encoder_only": c.steps_encoder_only,
            "gyro_timeouts": c.gyro_timeouts,
            "gyro_stale": self.gyro_stale,
            "gyro_misaligned": c.gyro_misaligned,
            "gyro_merges": c.gyro_merges,
            "gyro_postponed": self._align.postponed,
            "odometry_heading_rejected": c.odometry_heading_rejected,
            "gyro_deferred_steps": self._align.deferrals,
            "bad_input": c.bad_input,
            "odometry_out_of_order": self._odo.out_of_order,
            "odometry_jumps": self._odo.jumps,
            "gyro_out_of_order": self._gyro.out_of_order,
            "gyro_discontinuities": self._gyro.discontinuities,
            "gyro_bias_radps": self._bias.bias_radps,
        }
