"""The MRCLAM EKF step by step: one filter over one or several robots, fed one message at a
time (what localization/mrclam_ekf.py's batch runner and localization/mrclam_service.py's
replay service both drive; the models and every default are in docs/algorithms.md).

:class:`JointEkf` holds, per robot, the state s = (x, y, theta, k, b, c, d, beta)
(localization/mrclam_motion.py, mrclam_camera.py) at the robot's own time, and one
covariance P over all its robots: the diagonal blocks are kept current; a cross block
P_ij is stored as of the last update that needed it, and the transitions Phi_i of each
robot's predictions since then are accumulated, so that P_ij = Phi_i P_ij Phi_j^T is
applied only when an update needs the cross-covariances (exact, and cheap while the
robots only dead-reckon). A filter over one robot has no cross blocks.

- ``command(n, stamp, v, w)``: the commanded (v, w) act ``command_lag_s`` after their
  stamp and hold until the next (zero-order hold); ``process_to(n, t)`` applies those
  due by t and records a track row at every ``output_period_s`` from the robot's start.
- ``landmark``: the camera's range-bearing to a known landmark, gated (NIS against
  chi2_2(p) with the measurement's own noise), then the Kalman update with the noise
  inflated for the camera errors' correlation in time (AR(1)) and within a frame.
- ``robot_joint``: a measurement of robot j by robot n in one joint update of both
  (and of every robot correlated with them): the centralized filter.
- ``robot_split``: the same measurement by one robot's filter, with j's published
  estimate (mean and covariance, aged), fused by split covariance intersection
  (localization/covariance_intersection.py): the camera noise is independent, the two
  estimates of unknown correlation ("ci": everything of unknown correlation). It returns
  the observer's position fix of j, made from its prior, for ``fix_update`` of j.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, field

import numpy as np

from localization.covariance_intersection import split_ci_update, split_ci_weight
from localization.mrclam_camera import camera_measurement, camera_sigmas, target_position
from localization.mrclam_config import MrclamEkfConfig
from localization.mrclam_motion import IBETA, IC, ID, IE, IK, IKW, IQ, IU, IV, NX, biased_motion
from numerics import ekf
from numerics.angles import wrap_angle

#: A published estimate: (time, mean (x, y, theta), covariance 3 x 3).
Estimate = tuple[float, np.ndarray, np.ndarray]
#: A robot's name in a filter: the batch's subject numbers, the replay's "r<n>".
RobotId = int | str


def ar1_inflation(dt: float, tau: float) -> float:
    """(1 + rho) / (1 - rho) with rho = exp(-dt / tau): the variance factor under which
    errors of an AR(1) process sampled every dt carry, summed, the information they
    really hold (the long-run variance of their mean); 1 for tau <= 0 or the first."""
    if tau <= 0.0 or not dt < math.inf:
        return 1.0
    rho = math.exp(-max(dt, 1e-9) / tau)
    return (1.0 + rho) / (1.0 - rho)


def frame_factor(k: int, rho: np.ndarray) -> np.ndarray:
    """Variance factor of the k-th measurement (k >= 1) of a frame whose errors are
    equicorrelated at rho: k of them carry k / (1 + (k - 1) rho) measurements' worth."""
    if k <= 1:
        return np.ones_like(rho)
    info = k / (1.0 + (k - 1) * rho) - (k - 1) / (1.0 + (k - 2) * rho)
    with np.errstate(divide="ignore"):
        return 1.0 / info  # inf at rho = 1: the k-th adds nothing


@dataclass(frozen=True)
class PositionFix:
    """Robot ``observer`` saw robot ``robot`` at ``p`` (x, y) at time ``t``: from the
    observer's prior estimate (covariance part ``c_dep``, of unknown correlation with the
    robot's own estimate) and its measurement (``c_ind``, the camera noise: independent)."""

    t: float
    robot: RobotId
    observer: RobotId
    p: np.ndarray
    c_dep: np.ndarray
    c_ind: np.ndarray


@dataclass
class RobotState:
    """One robot in a :class:`JointEkf`: its state at time ``t``, held and queued
    commands, the grid of its track, its recorded rows and counts."""

    n: RobotId
    s: np.ndarray
    t: float
    t0: float
    v: float = 0.0
    w: float = 0.0
    queue: deque = field(default_factory=deque)
    phi: np.ndarray | None = None  # transitions since the cross blocks were last applied
    next_grid: int = 0
    rows: list = field(default_factory=list)  # (t, mean (3,), cov (3, 3), on_grid)
    last_grid: Estimate | None = None
    counts: Counter = field(default_factory=Counter)
    gated: list = field(default_factory=list)  # (t, subject, NIS)


class JointEkf:
    """The EKF over the robots added to it (module docstring)."""

    def __init__(self, cfg: MrclamEkfConfig, landmarks: dict[int, tuple]) -> None:
        self.cfg, self.marks, self.gate = cfg, dict(landmarks), cfg.gate
        self.r: dict[RobotId, RobotState] = {}
        self.at: dict[RobotId, int] = {}  # robot -> offset of its block in P
        self.P = np.zeros((0, 0))
        self.correlated = False
        # (robot, subject or 0): (time of the last measurement used, 0);
        # (robot, -1): (time of its current camera frame, measurements used in it)
        self.last: dict[tuple[RobotId, RobotId], tuple[float, int]] = {}
        self.rho = np.asarray(cfg.frame_correlation, float)
        c = cfg
        self.q_cam = np.array(
            [
                c.camera_scale_sigma,
                c.camera_offset_sigma_m,
                c.camera_bearing_sigma_rad,
                c.camera_slope_sigma,
                c.camera_distortion_sigma,
            ]
        )
        self.q_cam = self.q_cam**2 / c.camera_drift_s
        self.white = np.asarray(c.error_white_fraction, float)
        self.target = np.asarray(c.error_target_fraction, float)

    def add_robot(self, n: RobotId, t0: float, pose: np.ndarray, cov3: np.ndarray) -> None:
        """Robot n from time t0 at ``pose`` with covariance ``cov3``; its biases and
        camera states at 0 with their prior sigmas."""
        c = self.cfg
        s = np.zeros(NX)
        s[:3] = pose
        k = len(self.r) * NX
        p = np.zeros((k + NX, k + NX))
        p[:k, :k] = self.P
        b = p[k:, k:]
        b[:3, :3] = cov3
        sig = (
            c.speed_scale_sigma,
            c.turn_scale_sigma,
            c.camera_scale_sigma,
            c.camera_offset_sigma_m,
            c.camera_bearing_sigma_rad,
            c.camera_slope_sigma,
            c.camera_distortion_sigma,
            *c.camera_common_sigma,
        )
        for i, sg in zip((IK, IKW, IC, ID, IBETA, IE, IQ, IU, IV), sig, strict=True):
            b[i, i] = sg * sg
        self.P, self.at[n] = p, k
        self.r[n] = RobotState(n, s, t0, t0)
        self._grid(n, t0)

    def _b(self, n: RobotId) -> slice:
        return slice(self.at[n], self.at[n] + NX)

    # ------------------------------------------------------------------ time
    def command(self, n: RobotId, stamp: float, v: float, w: float) -> None:
        self.r[n].counts["odometry"] += 1
        self.r[n].queue.append((stamp + self.cfg.command_lag_s, v, w))

    def process_to(self, n: RobotId, t: float) -> None:
        """Apply robot n's commands due by ``t`` and record its grid rows up to ``t``
        (the state itself stays at its last grid row or update)."""
        rs = self.r[n]
        while rs.queue and rs.queue[0][0] <= t:
            ta, v, w = rs.queue.popleft()
            if v != rs.v or w != rs.w:  # a new command: the old one acts until now
                self._grid(n, ta)
                self._predict(n, ta)
                rs.v, rs.w = v, w
        self._grid(n, t)

    def _grid(self, n: RobotId, t: float) -> None:
        rs, period = self.r[n], self.cfg.output_period_s
        while (tg := rs.t0 + rs.next_grid * period) <= t:
            self._predict(n, tg)
            self._record(n, True)
            rs.next_grid += 1

    def _record(self, n: RobotId, grid: bool) -> None:
        rs, b = self.r[n], self._b(n)
        row = (rs.t, rs.s[:3].copy(), self.P[b, b][:3, :3].copy(), grid)
        rs.rows.append(row)
        if grid:
            rs.last_grid = row[:3]

    def _predict(self, n: RobotId, t: float) -> None:
        """Integrate the held command from the robot's time to ``t``: P' = F P F^T +
        G Q G^T + Q_bias + Q_camera, Q = diag(q_v, q_w) / dt the white velocity noise of
        intensity q_v = (v0 + kv |v|)^2 window, q_w = w_noise_time + w_noise_turn |w|
        (G grows with dt: the pose noise grows in proportion to dt; docs/algorithms.md)."""
        rs = self.r[n]
        dt = t - rs.t
        if dt <= 0.0:
            return
        c = self.cfg
        s, f, g = biased_motion(rs.s, rs.v, rs.w, dt, c.bias_tau_s, c.camera_common_tau_s)
        sv = c.v_sigma_mps + c.v_sigma_rel * abs(rs.v)
        qv = sv * sv * c.noise_window_s
        qw = c.w_noise_time + c.w_noise_turn * abs(rs.w)
        b = self._b(n)
        p = ekf.predict_covariance(self.P[b, b], f, g, np.diag([qv / dt, qw / dt]))
        a2 = f[IK, IK] ** 2
        p[IK, IK] += c.speed_scale_sigma**2 * (1.0 - a2)
        p[IKW, IKW] += c.turn_scale_sigma**2 * (1.0 - a2)
        p[IC:IU, IC:IU] += np.diag(self.q_cam * dt)
        for i, sg in zip((IU, IV), c.camera_common_sigma, strict=True):
            p[i, i] += sg * sg * (1.0 - f[i, i] ** 2)
        self.P[b, b] = p
        if self.correlated:
            rs.phi = f if rs.phi is None else f @ rs.phi
        rs.s, rs.t = s, t

    def _sync(self) -> None:
        """Apply the accumulated transitions to the cross blocks."""
        if not any(rs.phi is not None for rs in self.r.values()):
            return
        m = np.eye(self.P.shape[0])
        for n, rs in self.r.items():
            if rs.phi is not None:
                m[self._b(n), self._b(n)] = rs.phi
                rs.phi = None
        diag = [self.P[self._b(n), self._b(n)].copy() for n in self.r]
        self.P = m @ self.P @ m.T
        for n, d in zip(self.r, diag, strict=True):
            self.P[self._b(n), self._b(n)] = d

    def to(self, n: RobotId, t: float) -> RobotState:
        """Robot n processed and predicted to ``t``."""
        self.process_to(n, t)
        self._predict(n, t)
        return self.r[n]

    # ------------------------------------------------------------------ noise
    def _noise(self, n: RobotId, subj: RobotId, t: float, r_hat: float):
        """(R, R inflated, token for _used) of robot n's measurement at t: the camera
        sigmas at the predicted range without the common part (in the state), R = its
        white and per-target parts; inflated: the white part by the frame factor of the
        k-th measurement used in this frame, the per-target part by the AR(1) factor of
        the time since the target's (or, by scope, the robot's) last measurement used."""
        c = self.cfg
        key = (n, subj if c.correlation_scope == "subject" else 0)
        frame = self.last.get((n, -1))
        k = frame[1] + 1 if frame is not None and t - frame[0] <= c.frame_gap_s else 1
        frame_t = frame[0] if k > 1 else t
        last = self.last.get(key)
        dt = math.inf if last is None else t - last[0]
        sr, sb = camera_sigmas(
            r_hat,
            c.range_sigma_m,
            c.range_sigma_rel,
            c.range_sigma_quad,
            c.bearing_sigma_rad,
            c.bearing_sigma_lateral_m,
        )
        var = np.array([sr * sr, sb * sb])
        ar1 = np.array([ar1_inflation(dt, tau) for tau in c.error_correlation_s])
        infl = self.white * frame_factor(k, self.rho) + self.target * ar1
        return (
            np.diag(var * (self.white + self.target)),
            np.diag(var * infl),
            (key, (t, 0), (n, -1), (frame_t, k)),
        )

    def _psi(self, z: np.ndarray) -> float | None:
        """The bearing at which the range's factor is taken (None: the predicted)."""
        return float(z[1]) if self.cfg.range_factor_bearing == "measured" else None

    def _used(self, token) -> None:
        self.last[token[0]] = token[1]
        self.last[token[2]] = token[3]

    # ------------------------------------------------------------------ updates
    def _kalman(self, hs: dict[RobotId, np.ndarray], nu, r_gate, r_upd, n, subj, t, kind) -> bool:
        """Gate and update the robots of ``hs`` (robot -> 2 x NX Jacobian), and with them
        every robot correlated with them; True when accepted."""
        ids = list(self.r) if self.correlated else list(hs)
        if self.correlated:
            self._sync()
        idx = np.concatenate([np.arange(self.at[i], self.at[i] + NX) for i in ids])
        h = np.concatenate([hs.get(i, np.zeros((2, NX))) for i in ids], axis=1)
        p = self.P[np.ix_(idx, idx)]
        ph = p @ h.T
        hph = h @ ph
        d2 = ekf.nis(nu, np.linalg.inv(hph + r_gate))
        if not d2 <= self.gate:
            self.r[n].counts[f"{kind}_gated"] += 1
            self.r[n].gated.append((t, subj, d2))
            return False
        x = np.concatenate([self.r[i].s for i in ids])
        x, p = ekf.joseph_update(x, p, nu, h, r_upd, ph, np.linalg.inv(hph + r_upd))
        self.P[np.ix_(idx, idx)] = 0.5 * (p + p.T)
        for k, i in enumerate(ids):
            self.r[i].s = x[k * NX : (k + 1) * NX]
        if len(hs) > 1:
            self.correlated = True
        return True

    def landmark(self, n: RobotId, t: float, subj: int, z: np.ndarray) -> None:
        """Robot n's range-bearing ``z`` to landmark ``subj`` at ``t``."""
        rs, mark, c = self.to(n, t), self.marks[subj], self.cfg
        if math.hypot(mark[0] - rs.s[0], mark[1] - rs.s[1]) < 1e-6:
            rs.counts["landmark_on_robot"] += 1
            return
        zhat, hs, hm, tm = camera_measurement(rs.s, mark[0], mark[1], c.camera_model, self._psi(z))
        r, ri, token = self._noise(n, subj, t, math.hypot(mark[0] - rs.s[0], mark[1] - rs.s[1]))
        r, ri = tm @ r @ tm.T, tm @ ri @ tm.T
        rm = hm @ np.diag([mark[2] ** 2, mark[3] ** 2]) @ hm.T  # the surveyed position
        nu = np.array([z[0] - zhat[0], wrap_angle(z[1] - zhat[1])])
        if self._kalman({n: hs}, nu, r + rm, ri + rm, n, subj, t, "landmark"):
            self._used(token)
            rs.counts["landmark_accepted"] += 1
            self._record(n, False)

    def robot_joint(self, n: RobotId, t: float, j: RobotId, z: np.ndarray) -> None:
        """Robot n's range-bearing ``z`` to robot j at ``t``, one update of both."""
        rs, rj = self.to(n, t), self.to(j, t)
        rng = math.hypot(rj.s[0] - rs.s[0], rj.s[1] - rs.s[1])
        if rng < 1e-6:
            rs.counts["robot_on_robot"] += 1
            return
        zhat, hs, hm, tm = camera_measurement(
            rs.s, rj.s[0], rj.s[1], self.cfg.camera_model, self._psi(z)
        )
        zhat[0] += self.cfg.robot_target_offset_m
        hj = np.zeros((2, NX))
        hj[:, :2] = hm
        r, ri, token = self._noise(n, j, t, rng)
        r, ri = tm @ r @ tm.T, tm @ ri @ tm.T
        nu = np.array([z[0] - zhat[0], wrap_angle(z[1] - zhat[1])])
        if self._kalman({n: hs, j: hj}, nu, r, ri, n, j, t, "robot"):
            self._used(token)
            rs.counts["robot_accepted"] += 1
            rj.counts["seen_accepted"] += 1
            self._record(n, False)
            self._record(j, False)

    def robot_split(
        self, n: RobotId, t: float, j: RobotId, z: np.ndarray, peer: Estimate | None, both: bool
    ) -> PositionFix | None:
        """Robot n's range-bearing ``z`` to robot j at ``t``, fused with j's published
        estimate ``peer`` by split CI ("ci": CI); the position fix of j from n's prior
        (when ``both``), or None."""
        if self.correlated:
            raise ValueError("robot_split is for a filter of one robot")
        if peer is None:
            self.process_to(n, t)
            self.r[n].counts["robot_no_estimate"] += 1
            return None
        rs, c = self.to(n, t), self.cfg
        tj, mj, cj = peer
        rng = math.hypot(mj[0] - rs.s[0], mj[1] - rs.s[1])
        if rng < 1e-6:
            rs.counts["robot_on_robot"] += 1
            return None
        cpos = cj[:2, :2] + np.eye(2) * (c.peer_speed_mps * (t - tj)) ** 2
        zhat, hs, hm, tm = camera_measurement(rs.s, mj[0], mj[1], c.camera_model, self._psi(z))
        zhat[0] += c.robot_target_offset_m
        r, ri, token = self._noise(n, j, t, rng)
        ri_z = ri  # the camera noise of z itself, for the position fix
        r, ri = tm @ r @ tm.T, tm @ ri @ tm.T
        a_peer = hm @ cpos @ hm.T
        b = self._b(n)
        p = self.P[b, b]
        nu = np.array([z[0] - zhat[0], wrap_angle(z[1] - zhat[1])])
        d2 = ekf.nis(nu, np.linalg.inv(hs @ p @ hs.T + a_peer + r))
        if not d2 <= self.gate:
            rs.counts["robot_gated"] += 1
            rs.gated.append((t, j, d2))
            return None
        fix = None
        zc = np.array([z[0] - c.robot_target_offset_m, z[1]])
        inv = target_position(rs.s, zc, c.camera_model) if both else None
        if inv is not None:
            pj, js, jz = inv
            c_dep, c_ind = js @ p @ js.T, jz @ ri_z @ jz.T
            if c.cooperation == "ci":
                c_dep, c_ind = c_dep + c_ind, np.zeros((2, 2))
            fix = PositionFix(t, j, n, pj, c_dep, c_ind)
        r_dep, r_ind = (a_peer, ri) if c.cooperation == "split_ci" else (a_peer + ri, 0 * ri)
        w = split_ci_weight(p, hs, r_dep, r_ind, c.ci_criterion, block=3)
        rs.s, self.P[b, b] = split_ci_update(rs.s, p, nu, hs, r_dep, r_ind, w)
        self._used(token)
        rs.counts["robot_accepted" if w < 1.0 else "robot_no_gain"] += 1
        if w < 1.0:
            self._record(n, False)
        return fix

    def fix_update(self, n: RobotId, fix: PositionFix) -> None:
        """Robot n seen by another robot: its position fix, fused by split CI."""
        rs, c = self.to(n, fix.t), self.cfg
        b = self._b(n)
        p = self.P[b, b]
        h = np.zeros((2, NX))
        h[0, 0] = h[1, 1] = 1.0
        nu = fix.p - rs.s[:2]
        d2 = ekf.nis(nu, np.linalg.inv(p[:2, :2] + fix.c_dep + fix.c_ind))
        if not d2 <= self.gate:
            rs.counts["seen_gated"] += 1
            rs.gated.append((fix.t, fix.observer, d2))
            return
        w = split_ci_weight(p, h, fix.c_dep, fix.c_ind, c.ci_criterion, block=3)
        rs.s, self.P[b, b] = split_ci_update(rs.s, p, nu, h, fix.c_dep, fix.c_ind, w)
        rs.counts["seen_accepted" if w < 1.0 else "seen_no_gain"] += 1
        if w < 1.0:
            self._record(n, False)
