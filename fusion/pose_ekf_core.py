"""Pose EKF state (x, y, theta [, GPS bias]) and its predict/update steps (ekf-vs-cp eq. 1-4).

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
(fusion.ekf_update, with the gates and counters): a position (``update_position``, the
GPS antenna's, through the lever arm and the bias states) and an absolute heading
(``update_heading``, e.g. a compass or an aligned gyro).

Gating: every measurement's squared Mahalanobis distance (NIS) nu^T S^-1 nu is compared
with the chi-square quantile of its dimension at ``gate_probability`` (default 0.99:
9.21 for GPS with 2 dof, 6.63 for the gyro step and the heading with 1 dof, from
numerics.chi2); beyond it the measurement is rejected and counted (gps_rejected,
heading_rejected). For the gyro step the verdict goes the other way: the gyro integrates
a rate and cannot jump, the encoders can (a bad or stale SIP, a spinning wheel), so the
encoders' heading change is the outlier and is replaced by the gyro's
(odometry_heading_rejected). ``gate_probability=None`` turns gating off.

:class:`PoseEkfCore` is what the gyro/odometry alignment front end drives (the
fusion.alignment.AlignedFilter protocol: ``predict_step``, ``correct_deferred`` for steps
predicted before the gyro caught up with them, ``turn``); fusion.pose_ekf.PoseEkf adds
the message-level intake. Array-level API: predict(dl, dr, dtheta_gyro=None,
gyro_var=None), update_position(z, R), update_heading(theta, var) -> UpdateResult.
"""

from __future__ import annotations

import math

import numpy as np

from fusion import models
from fusion.alignment import Deferred
from fusion.ekf_update import EkfCounters, UpdateResult, is_pd, joseph_update, repair_pd
from fusion.increments import OdometryStep
from fusion.pose_ekf_params import PoseEkfParams
from msgs import Interval, Pose2D, PoseBox, PoseEstimate, wrap_angle
from numerics.ekf import predict_covariance


class PoseEkfCore:
    """EKF state on (x, y, theta [, GPS bias]) with its predict/update (module docstring)."""

    def __init__(self, params: PoseEkfParams | None = None, initial: Pose2D | None = None):
        self.params = p = params or PoseEkfParams()
        self._gates = {1: p.gate(1), 2: p.gate(2)}
        self.heading_gate = self._gates[1]
        self._count = EkfCounters()
        self.last_nis: dict[str, float] = {"gps": math.nan, "gyro": math.nan, "heading": math.nan}
        self._initial = initial
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
        """Restart the state at ``pose`` (default: the initial one); counters are kept.
        Without a pose, the position is unknown until :meth:`init_from_fix`."""
        known = pose is not None or self._initial is not None
        pose = pose or self._initial or Pose2D()
        self.x = np.zeros(self.params.n_states)
        self.x[:3] = [pose.x, pose.y, wrap_angle(pose.theta)]
        self.P = self._initial_cov()
        self.stamp_ns = int(stamp_ns)
        self._pose_set = known
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
            rg = gyro_var if gyro_var is not None else self.gyro_variance(dtheta_gyro, 0.0)
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

    def gyro_variance(self, dtheta_gyro: float, dt_s: float) -> float:
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
        gate = self._gates.get(dof)
        if gate is None:  # (a .get default would compute the quantile at every update)
            gate = self._gates[dof] = self.params.gate(dof)
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

    # -- what the alignment front end calls (fusion.alignment.AlignedFilter) ----------
    def _wheels(self, step: OdometryStep) -> tuple[float, float]:
        dl, dr = models.step_to_wheels(step.ds_m, step.dtheta_rad, self.params.wheelbase_m)
        return float(dl), float(dr)

    def encoder_variance(self, step: OdometryStep) -> float:
        """Q_u[1, 1] of the step: the variance of its encoder heading change (eq. 1)."""
        p = self.params
        dl, dr = self._wheels(step)
        qu = models.step_covariance(
            dl, dr, p.wheelbase_m, p.wheel_noise_m_per_sqrt_m,
            p.wheel_noise_floor_m, p.turn_noise_fraction,
        )  # fmt: skip
        return float(qu[1, 1])

    def position(self) -> tuple[float, float]:
        return float(self.x[0]), float(self.x[1])

    def predict_step(self, step: OdometryStep, dtheta_gyro: float | None, covered_s: float) -> None:
        """:meth:`predict` over an odometry step, with the gyro's change over ``covered_s``."""
        dl, dr = self._wheels(step)
        if dtheta_gyro is None:
            self.predict(dl, dr, dt_s=step.dt_s)
        else:
            rg = self.gyro_variance(dtheta_gyro, covered_s)
            self.predict(dl, dr, dtheta_gyro, rg, dt_s=step.dt_s)

    def correct_deferred(self, d: Deferred, dtheta_gyro: float, covered_s: float) -> None:
        """The gyro's change over a deferred interval, fused retroactively.

        The deferred steps were predicted on the encoders (heading moved by their sum E,
        dtheta variance sum Sw). The gyro's change G is a measurement of the same sum:
        innovation G - E, S = Sw + Rg, gated like a single step (beyond the gate the
        encoders are the outlier: K = 1). The heading moves by K (G - E), P_theta loses
        K Sw, and the position driven meanwhile is rotated about its start by half the
        correction. Approximate (the cross-covariances are kept): used only after stalls.
        """
        rg = self.gyro_variance(dtheta_gyro, covered_s)
        nu = dtheta_gyro - d.dtheta_enc
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
        self.x[0], self.x[1] = d.rotate(self.x[0], self.x[1], 0.5 * delta)
        self.x[2] = wrap_angle(self.x[2] + delta)
        pt = self.P.copy()
        pt[2, 2] = max(pt[2, 2] - k * d.var_enc + (rg if k == 1.0 else 0.0), 1e-12)
        if not is_pd(pt):
            pt = repair_pd(pt)
            self._count.covariance_repairs += 1
        self.P = 0.5 * (pt + pt.T)
        self._count.gyro_merges += 1

    def turn(self, dtheta_gyro: float, covered_s: float) -> None:
        self.x[2] = wrap_angle(self.x[2] + dtheta_gyro)
        self.P[2, 2] += self.gyro_variance(dtheta_gyro, covered_s)

    def init_from_fix(self, z: np.ndarray, r: np.ndarray) -> None:
        """Set the position from a GPS fix (z, R) when no pose was given; the heading
        stays. With bias states the position error is -(bias error) - white noise."""
        p = self.params
        lever = models.position_measurement(np.array([0.0, 0.0, self.x[2]]), p.gps_lever_m)[0]
        self.x[:2] = z - lever - (self.x[3:5] if p.gps_bias_states else 0.0)
        self.P[:2, :] = 0.0
        self.P[:, :2] = 0.0
        self.P[:2, :2] = r
        if p.gps_bias_states:
            pb = self.P[3:5, 3:5]
            self.P[:2, :2] = r + pb
            self.P[:2, 3:5] = -pb
            self.P[3:5, :2] = -pb
        self._pose_set = True
