"""Pose EKF on (x, y, theta): wheel odometry, gyro and GPS (ekf-vs-cp.txt §2.1-2.2, eq. 1-4).

Prediction (eq. 2-4) on every odometry step: the wheel displacements (dl, dr) — recovered
from the robot's odometry pose deltas with the configured wheel base, fusion.models — with
independent wheel noise k^2 |d| + floor^2, give the step u = (ds, dtheta) and its
covariance Q_u = J Q_wheels J^T (eq. 1), plus (beta dtheta)^2 on dtheta for the wheel
base's uncertainty while turning (beta = 0.1, as ir-grid-mapping eq. 4 found). If the
gyro reported over the same interval, its heading change dtheta_g (bias learnt at rest
removed; variance (gamma dtheta_g)^2 + arw^2 dt + (bias_sigma dt)^2) is a second
measurement of dtheta: it is fused into u first (Kalman update of the input: innovation
dtheta_g - dtheta, S = Q_u[1,1] + R_g), which is exact for an increment measurement,
unlike treating the drifting gyro angle as an absolute heading. Then x = f(x, u),
P = F P F^T + G Q_u G^T (eq. 4, A = F, W = G).

GPS bias states (``gps_bias_states``, on by default): the state is augmented with the
receiver's bias (b_east, b_north), a first-order Gauss-Markov process (fusion.models:
b' = exp(-dt/tau) b + w, stationary sigma ``gps_bias_sigma_m``, tau ``gps_bias_tau_s``;
defaults and their source in fusion.pose_ekf_params), propagated at every odometry step
over its dt; a fix measures antenna position + b with R the white part of its claimed
sigma. Without it the filter takes each fix's whole error as white and its 3-sigma box
stops containing the truth on long runs (bench/pose_ekf.py). ``x`` and ``P`` hold the
full state; estimates and bounds give the pose block.

Updates (eq. 4), Joseph form P = (I - K H) P (I - K H)^T + K R K^T, symmetrised, with a
Cholesky check that repairs (and counts) a covariance that lost positive definiteness
(fusion.ekf_update, with the gates and counters):
- GPS position (GpsFix.east_m/north_m, local metres of the NMEA driver): R from the GST
  standard deviations when present, else per-axis sigma = HDOP x UERE / sqrt(2) (HDOP x
  UERE is the horizontal DRMS); fixes without a 2D/3D fix or local metres are counted
  (gps_no_fix) and skipped. A fix whose stamp is older than the filter time by more than
  ``gps_max_lag_s``, or not newer than the previous fix, is rejected and counted
  (out_of_order_gps); a fix within the lag is applied now with R inflated by
  (speed x lag)^2, the distance driven meanwhile. A receiver's error is not white: it
  wanders with a correlation time of minutes (satellite geometry, ionosphere), so fixes
  taken every second are far from independent and an EKF treating them as white grows
  over-confident (its 3-sigma box stops containing the truth, the very point ekf-vs-cp
  makes). ``gps_error_correlation_s`` = tau > 0 scales R by max(1, tau / dt), dt the time
  since the last fix used: the fixes of one correlation time together carry about the
  information of one. Off (0) by default; bench/pose_ekf.py shows both.
- absolute heading (``update_heading``, e.g. a compass or an aligned gyro).

Gating: every measurement's squared Mahalanobis distance (NIS) nu^T S^-1 nu is compared
with the chi-square quantile of its dimension at ``gate_probability`` (default 0.99:
9.21 for GPS with 2 dof, 6.63 for the gyro step and the heading with 1 dof, from
scipy.stats.chi2.ppf); beyond it the measurement is rejected and counted (gps_rejected,
heading_rejected). For the gyro step the verdict goes the other way: the gyro integrates
a rate and cannot jump, the encoders can (a bad or stale SIP, a spinning wheel), so the
encoders' heading change is the outlier and is replaced by the gyro's
(odometry_heading_rejected). Which gyro change goes with which odometry step (late and
bunched messages after a stall) is decided by fusion.alignment. ``gate_probability=None`` turns gating off.

Timeouts: a sensor silent for longer than its timeout (relative to the odometry stamps)
is flagged stale (``gps_stale``, ``gyro_stale``; transitions counted) and the filter
predicts on odometry alone. Odometry not newer than the last one is counted and skipped.

Initial pose: ``initial`` (or ``set_pose``); without one, the first GPS fix sets x, y
and the heading stays at 0 with ``initial_sigma_theta_rad`` — give the start heading with
``set_pose`` when it is not east (the EKF cannot find a wholly unknown heading).

Output: ``PoseEstimate`` (frame ``map``) and ``bounds(k=3)`` -> ``PoseBox`` with the
k-sigma interval of each coordinate, to compare with constraint propagation's boxes.

Message-level API (what the daemon calls):
    ekf = PoseEkf(PoseEkfParams(...), initial=Pose2D(...))
    ekf.feed(msg) -> PoseEstimate | None   # RobotOdometry / GpsFix -> estimate; GyroSample -> None
    ekf.feed_odometry(m), ekf.feed_gyro(m), ekf.feed_gps(m)
    ekf.estimate() -> PoseEstimate; ekf.bounds(3.0) -> PoseBox
    ekf.set_pose(pose, stamp_ns=None, covariance=None); ekf.reset()
    ekf.counters() -> dict (for diagnostics); ekf.stale(now_ns) -> dict[str, bool]
Array-level API: predict(dl, dr, dtheta_gyro=None, gyro_var=None),
update_position(z, R), update_heading(theta, var) -> UpdateResult.
"""

from __future__ import annotations

import math

import numpy as np

from fusion import models
from fusion.alignment import Deferred, GyroAlignment
from fusion.ekf_update import (
    EkfCounters,
    UpdateResult,
    is_pd,
    joseph_update,
    repair_pd,
)
from fusion.increments import GyroDelta, GyroDeltas, OdometryDeltas, RestBias
from fusion.pose_ekf_params import DEG, PoseEkfParams, gps_fix_measurement
from msgs import (
    GpsFix,
    GyroSample,
    Interval,
    Pose2D,
    PoseBox,
    PoseEstimate,
    RobotOdometry,
    wrap_angle,
)
from numerics.ekf import predict_covariance

NS = 1e-9
__all__ = ["DEG", "PoseEkf", "PoseEkfParams", "UpdateResult"]


class PoseEkf:
    """EKF on (x, y, theta) fed odometry, gyro and GPS (see module docstring)."""

    def __init__(self, params: PoseEkfParams | None = None, initial: Pose2D | None = None):
        self.params = p = params or PoseEkfParams()
        self._gates = {1: p.gate(1), 2: p.gate(2)}
        self._odo = OdometryDeltas()
        self._gyro = GyroDeltas()
        self._align = GyroAlignment(self._gyro, p.gyro_max_lag_s, p.gyro_max_defer_s)
        self._bias = RestBias(p.bias_window_s, p.bias_min_rest_s)
        self._count = EkfCounters()
        self.last_nis: dict[str, float] = {"gps": math.nan, "gyro": math.nan, "heading": math.nan}
        self.gps_stale = True
        self.gyro_stale = True
        self._initial = initial
        self._speed_mps = 0.0
        self._last_gps_ns: int | None = None
        self._last_gps_used_ns: int | None = None
        self.reset(initial)
        self._count.resets = 0

    # -- state -----------------------------------------------------------------------
    def _initial_cov(self) -> np.ndarray:
        p = self.params
        d = [p.initial_sigma_xy_m**2, p.initial_sigma_xy_m**2, p.initial_sigma_theta_rad**2]
        if p.gps_bias_states:
            d += [p.gps_bias_sigma_m**2] * 2
        return np.diag(d)

    def reset(self, pose: Pose2D | None = None, stamp_ns: int = 0) -> None:
        """Forget everything but the counters; restart at ``pose`` (default: the initial one).

        Without a pose the filter re-initialises its position from the next GPS fix when
        ``init_from_gps`` is set.
        """
        known = pose is not None or self._initial is not None
        pose = pose or self._initial or Pose2D()
        self.x = np.zeros(self.params.n_states)
        self.x[:3] = [pose.x, pose.y, wrap_angle(pose.theta)]
        self.P = self._initial_cov()
        self.stamp_ns = int(stamp_ns)
        self._pose_set = known
        self._odo.reset()
        self._gyro.reset()
        self._align.reset()
        self._last_gps_ns = None
        self._last_gps_used_ns = None
        self._speed_mps = 0.0
        self._count.resets += 1

    def set_pose(
        self,
        pose: Pose2D,
        stamp_ns: int | None = None,
        covariance: np.ndarray | tuple[float, ...] | None = None,
    ) -> None:
        """Set the pose (and its covariance, 3x3 or 9 values; default the initial one).
        The GPS bias states, if any, are kept, uncorrelated with the new pose."""
        cov = self._initial_cov()[:3, :3] if covariance is None else np.asarray(covariance, float)
        cov = cov.reshape(3, 3)
        if not np.all(np.isfinite(cov)) or not is_pd(cov):
            raise ValueError(
                "set_pose: covariance must be a finite symmetric positive-definite 3x3"
            )
        if not all(math.isfinite(v) for v in (pose.x, pose.y, pose.theta)):
            raise ValueError(f"set_pose: pose must be finite, got {pose}")
        self.x[:3] = [pose.x, pose.y, wrap_angle(pose.theta)]
        self.P[:3, :] = 0.0
        self.P[:, :3] = 0.0
        self.P[:3, :3] = 0.5 * (cov + cov.T)
        if stamp_ns is not None:
            self.stamp_ns = int(stamp_ns)
        self._pose_set = True

    @property
    def pose(self) -> Pose2D:
        return Pose2D(float(self.x[0]), float(self.x[1]), float(self.x[2]))

    @property
    def gps_bias_m(self) -> tuple[float, float]:
        """The estimated GPS bias (east, north), zeros without bias states."""
        if not self.params.gps_bias_states:
            return (0.0, 0.0)
        return (float(self.x[3]), float(self.x[4]))

    @property
    def gyro_bias_radps(self) -> float:
        return self._bias.bias_radps

    def estimate(self) -> PoseEstimate:
        return PoseEstimate(
            stamp_ns=self.stamp_ns,
            pose=self.pose,
            covariance=tuple(float(v) for v in self.P[:3, :3].ravel()),
            frame=self.params.frame,
            source="pose_ekf",
        )

    def bounds(self, k: float = 3.0) -> PoseBox:
        """The k-sigma box on x, y, theta (theta not wrapped: lo/hi may pass +-pi)."""
        s = np.sqrt(np.maximum(np.diag(self.P)[:3], 0.0)) * k
        x, y, th = (float(v) for v in self.x[:3])
        return PoseBox(
            self.stamp_ns,
            self.params.robot,
            Interval(x - s[0], x + s[0]),
            Interval(y - s[1], y + s[1]),
            Interval(th - s[2], th + s[2]),
            frame=self.params.frame,
        )

    # -- array-level -----------------------------------------------------------------
    def predict(
        self,
        dl: float,
        dr: float,
        dtheta_gyro: float | None = None,
        gyro_var: float | None = None,
        dt_s: float = 0.0,
    ) -> UpdateResult | None:
        """Propagate by wheel displacements (m); fuse a gyro step (rad, variance rad^2);
        the GPS bias states (if any) by their Gauss-Markov model over ``dt_s``."""
        p = self.params
        if not (math.isfinite(dl) and math.isfinite(dr)):
            self._count.bad_input += 1
            return None
        u = models.wheels_to_step(dl, dr, p.wheelbase_m)
        qu = models.step_covariance(
            dl,
            dr,
            p.wheelbase_m,
            p.wheel_noise_m_per_sqrt_m,
            p.wheel_noise_floor_m,
            p.turn_noise_fraction,
        )
        result = None
        if dtheta_gyro is not None and math.isfinite(dtheta_gyro):
            rg = gyro_var if gyro_var is not None else self._gyro_var(dtheta_gyro, 0.0)
            s = qu[1, 1] + rg
            nu = dtheta_gyro - u[1]
            nis = nu * nu / s
            self.last_nis["gyro"] = nis
            accepted = nis <= self._gates[1]
            if accepted:
                k = qu[:, 1] / s
                u = u + k * nu
                qu = qu - np.outer(k, k) * s
                qu = 0.5 * (qu + qu.T)
                self._count.gyro_fused += 1
            else:
                # Encoders and gyro disagree beyond the gate over an aligned interval: the
                # gyro integrates a rate and cannot jump, the encoders can (a bad or stale
                # SIP, a wheel spinning): the encoders' heading change is the outlier.
                u = np.array([u[0], dtheta_gyro])
                qu = np.diag([qu[0, 0], rg])
                self._count.odometry_heading_rejected += 1
            result = UpdateResult("gyro", accepted, nis, 1)
        n = p.n_states
        f3, g3 = models.motion_jacobians(self.x[:3], u, p.heading_point)
        f, g, q = np.eye(n), np.zeros((n, 2)), np.zeros((n, n))
        f[:3, :3], g[:3, :] = f3, g3
        self.x[:3] = models.motion(self.x[:3], u, p.heading_point)
        if p.gps_bias_states:
            self.x[3:5], a, qb = models.gauss_markov(
                self.x[3:5], dt_s, p.gps_bias_tau_s, p.gps_bias_sigma_m
            )
            f[3, 3] = f[4, 4] = a
            q[3, 3] = q[4, 4] = qb
        self.P = predict_covariance(self.P, f, g, qu) + q
        self.P = 0.5 * (self.P + self.P.T)
        self._count.predictions += 1
        return result

    def _gyro_var(self, dtheta_gyro: float, dt_s: float) -> float:
        p = self.params
        return (
            (p.gyro_gamma * dtheta_gyro) ** 2
            + p.gyro_arw_rad_per_sqrt_s**2 * dt_s
            + (p.gyro_bias_sigma_radps * dt_s) ** 2
            + 1e-14
        )

    def update_position(self, z: np.ndarray, r: np.ndarray, kind: str = "gps") -> UpdateResult:
        """Position measurement z (2,) with covariance R (2x2), gated."""
        if self.params.gps_bias_states and kind == "gps":
            h, hj = models.biased_position_measurement(self.x, self.params.gps_lever_m)
        else:
            h, hj = models.position_measurement(self.x[:3], self.params.gps_lever_m)
            hj = np.hstack([hj, np.zeros((2, self.x.size - 3))])
        nu = np.asarray(z, float) - h
        return self._update(kind, nu, hj, np.asarray(r, float))

    def update_heading(self, theta: float, var: float) -> UpdateResult:
        """Absolute heading measurement (rad, variance rad^2), gated."""
        h, hj = models.heading_measurement(self.x[:3])
        hj = np.hstack([hj, np.zeros((1, self.x.size - 3))])
        nu = np.array([wrap_angle(theta - h[0])])
        return self._update("heading", nu, hj, np.array([[var]]))

    def _update(self, kind: str, nu: np.ndarray, hj: np.ndarray, r: np.ndarray) -> UpdateResult:
        dof = nu.shape[0]
        if not (np.all(np.isfinite(nu)) and np.all(np.isfinite(r))):
            self._count.bad_input += 1
            return UpdateResult(kind, False, math.nan, dof)
        gate = self._gates.get(dof, self.params.gate(dof))
        x, pj, nis, accepted, repaired = joseph_update(self.x, self.P, nu, hj, r, gate)
        self.last_nis[kind] = nis
        if not accepted:
            self._bump(f"{kind}_rejected")
            return UpdateResult(kind, False, nis, dof)
        x[2] = wrap_angle(x[2])
        self.x, self.P = x, pj
        self._count.covariance_repairs += int(repaired)
        self._bump(f"{kind}_updates")
        return UpdateResult(kind, True, nis, dof)

    def _bump(self, name: str) -> None:
        if hasattr(self._count, name):
            setattr(self._count, name, getattr(self._count, name) + 1)
        else:
            self._count.extra[name] = self._count.extra.get(name, 0) + 1

    # -- message-level ---------------------------------------------------------------
    def feed(self, msg: object) -> PoseEstimate | None:
        """RobotOdometry / GpsFix -> the estimate (None if nothing changed); GyroSample -> None."""
        if isinstance(msg, RobotOdometry):
            return self.feed_odometry(msg)
        if isinstance(msg, GyroSample):
            self.feed_gyro(msg)
            return None
        if isinstance(msg, GpsFix):
            return self.feed_gps(msg)
        raise TypeError(f"PoseEkf is fed RobotOdometry, GyroSample or GpsFix, not {type(msg)}")

    def feed_gyro(self, msg: GyroSample) -> None:
        self._count.gyro += 1
        self._gyro.feed(msg)

    def feed_odometry(self, msg: RobotOdometry) -> PoseEstimate | None:
        """Predict over the motion since the previous odometry (fusing the gyro's step).

        The gyro's change is fused only over an interval it has caught up with
        (fusion.alignment); steps it lags behind are predicted on the encoders and
        corrected when it catches up (:meth:`_merge`).
        """
        self._count.odometry += 1
        step = self._odo.feed(msg)
        p = self.params
        if step is None:
            if self._odo.baselined:  # first message or re-baseline after a jump
                d = self._align.close()
                lost = self._align.baseline()
                if d is not None and lost is not None:
                    self._merge(d, lost)
                elif lost is not None:  # odometry jumped: the gyro alone turns the heading
                    dg = lost.angle_rad - self._bias.bias_radps * lost.covered_s
                    self.x[2] = wrap_angle(self.x[2] + dg)
                    self.P[2, 2] += self._gyro_var(dg, lost.covered_s)
                self.stamp_ns = max(self.stamp_ns, msg.stamp_ns)
                return self.estimate()
            return None
        decision, gyro = self._align.decide(step)
        if p.learn_bias_at_rest:
            self._bias.observe(step, gyro if decision == "fuse" else None)
        stale = self._align.silent_s > p.gyro_timeout_s
        if stale and not self.gyro_stale:
            self._count.gyro_timeouts += 1
        self.gyro_stale = stale
        if decision == "timeout":
            self._count.gyro_misaligned += 1
        dl, dr = models.step_to_wheels(step.ds_m, step.dtheta_rad, p.wheelbase_m)
        qu = models.step_covariance(
            float(dl), float(dr), p.wheelbase_m, p.wheel_noise_m_per_sqrt_m,
            p.wheel_noise_floor_m, p.turn_noise_fraction,
        )  # fmt: skip
        var_enc, x0, y0 = float(qu[1, 1]), float(self.x[0]), float(self.x[1])
        if decision == "fuse" and gyro is not None:
            dg = gyro.angle_rad - self._bias.bias_radps * gyro.covered_s
            rg = self._gyro_var(dg, gyro.covered_s)
            nu = dg - step.dtheta_rad
            if not step.at_rest and nu * nu / (var_enc + rg) > self._gates[1]:
                self._align.postpone(step, gyro, var_enc, x0, y0)
                self.predict(float(dl), float(dr), dt_s=step.dt_s)
            else:
                self.predict(float(dl), float(dr), dg, rg, dt_s=step.dt_s)
        else:
            if decision in ("deferred", "merged"):
                self._align.defer(step, var_enc, x0, y0)
            self.predict(float(dl), float(dr), dt_s=step.dt_s)
            if decision == "merged":
                d = self._align.close()
                if d is not None and gyro is not None:
                    self._merge(d, gyro)
        self.stamp_ns = step.t1_ns
        self._speed_mps = abs(step.ds_m) / step.dt_s if step.dt_s > 0 else 0.0
        gps_stale = self._last_gps_ns is None or (
            (step.t1_ns - self._last_gps_ns) * NS > p.gps_timeout_s
        )
        if gps_stale and not self.gps_stale:
            self._count.gps_timeouts += 1
        self.gps_stale = gps_stale
        return self.estimate()

    def _merge(self, d: Deferred, gyro: GyroDelta) -> None:
        """The gyro's change over a deferred interval, fused retroactively.

        The deferred steps were predicted on the encoders (heading moved by their sum E,
        dtheta variance sum Sw). The gyro's change G is a measurement of the same sum:
        innovation G - E, S = Sw + Rg, gated like a single step (beyond the gate the
        encoders are the outlier: K = 1). The heading moves by K (G - E), P_theta loses
        K Sw, and the position driven meanwhile is rotated about its start by half the
        correction. Approximate (the cross-covariances are kept): used only after stalls.
        """
        dg = gyro.angle_rad - self._bias.bias_radps * gyro.covered_s
        rg = self._gyro_var(dg, gyro.covered_s)
        nu = dg - d.dtheta_enc
        s = d.var_enc + rg
        nis = nu * nu / s
        self.last_nis["gyro"] = nis
        if nis <= self._gates[1] or not d.moving:
            k = d.var_enc / s
            self._count.gyro_fused += 1
        else:
            k = 1.0
            self._count.odometry_heading_rejected += 1
        delta = k * nu
        c, sn = math.cos(0.5 * delta), math.sin(0.5 * delta)
        ex, ey = self.x[0] - d.x0, self.x[1] - d.y0
        self.x[0], self.x[1] = d.x0 + c * ex - sn * ey, d.y0 + sn * ex + c * ey
        self.x[2] = wrap_angle(self.x[2] + delta)
        pt = self.P.copy()
        pt[2, 2] = max(pt[2, 2] - k * d.var_enc + (rg if k == 1.0 else 0.0), 1e-12)
        if not is_pd(pt):
            pt = repair_pd(pt)
            self._count.covariance_repairs += 1
        self.P = 0.5 * (pt + pt.T)
        self._count.gyro_merges += 1

    def gps_measurement(self, msg: GpsFix) -> tuple[np.ndarray, np.ndarray] | None:
        """(z, R) of a fix in local metres, or None when it has no usable position."""
        return gps_fix_measurement(msg, self.params)

    def feed_gps(self, msg: GpsFix) -> PoseEstimate | None:
        """Update on a fix; None if it was skipped (no fix, out of order, gated out)."""
        self._count.gps += 1
        meas = self.gps_measurement(msg)
        if meas is None:
            self._count.gps_no_fix += 1
            return None
        p = self.params
        lag_s = (self.stamp_ns - msg.stamp_ns) * NS
        if lag_s > p.gps_max_lag_s or (
            self._last_gps_ns is not None and msg.stamp_ns <= self._last_gps_ns
        ):
            self._count.out_of_order_gps += 1
            return None
        self._last_gps_ns = msg.stamp_ns
        self.gps_stale = False
        z, r = meas
        if not self._pose_set and p.init_from_gps:
            lever = models.position_measurement(np.array([0.0, 0.0, self.x[2]]), p.gps_lever_m)[0]
            self.x[:2] = z - lever - (self.x[3:5] if p.gps_bias_states else 0.0)
            self.P[:2, :] = 0.0
            self.P[:, :2] = 0.0
            self.P[:2, :2] = r
            if p.gps_bias_states:  # position error = -(bias error) - white noise
                pb = self.P[3:5, 3:5]
                self.P[:2, :2] = r + pb
                self.P[:2, 3:5] = -pb
                self.P[3:5, :2] = -pb
            self._pose_set = True
            self._count.gps_init += 1
            return self.estimate()
        tau = p.gps_error_correlation_s
        if tau > 0.0 and self._last_gps_used_ns is not None:
            gap_s = (msg.stamp_ns - self._last_gps_used_ns) * NS
            r = r * max(1.0, tau / max(gap_s, 1e-3))
        d = self._speed_mps * abs(lag_s)
        if d > 0.0:
            r = r + np.eye(2) * d * d
        res = self.update_position(z, r, "gps")
        if not res.accepted:
            return None
        self._last_gps_used_ns = msg.stamp_ns
        return self.estimate()

    # -- diagnostics -----------------------------------------------------------------
    def stale(self, now_ns: int) -> dict[str, bool]:
        """Which inputs have been silent longer than their timeout at ``now_ns``."""
        p = self.params
        last_o = self._odo.last.stamp_ns if self._odo.last is not None else None
        last_g = self._gyro.last_stamp_ns

        def old(t: int | None, timeout: float) -> bool:
            return t is None or (now_ns - t) * NS > timeout

        return {
            "odometry": old(last_o, p.odometry_timeout_s),
            "gyro": old(last_g, p.gyro_timeout_s),
            "gps": old(self._last_gps_ns, p.gps_timeout_s),
        }

    def counters(self) -> dict[str, int | float | bool]:
        c = self._count
        out: dict[str, int | float | bool] = {
            k: v for k, v in vars(c).items() if isinstance(v, int) and not isinstance(v, bool)
        }
        out.update(c.extra)
        out.update(
            {
                "out_of_order_odometry": self._odo.out_of_order,
                "odometry_jumps": self._odo.jumps,
                "out_of_order_gyro": self._gyro.out_of_order,
                "gyro_discontinuities": self._gyro.discontinuities,
                "gyro_postponed": self._align.postponed,
                "gyro_deferred_steps": self._align.deferrals,
                "gyro_stale": self.gyro_stale,
                "gps_stale": self.gps_stale,
                "gyro_bias_radps": self._bias.bias_radps,
            }
        )
        return out
