"""EKF localization of the MRCLAM robots (real data), alone or cooperative, for the
comparison with CP (issue 14 item 4). Models, noises, gating and covariance
intersection are derived in docs/algorithms.md ("EKF on MRCLAM"); in short:

**State and motion.** One filter per robot on s = (x, y, theta) (theta continuous). The
odometry is the commanded (v, w), held between samples (zero-order hold) and applied
``command_lag_s`` later than its stamp, since the motion-capture truth (and the camera)
trail the commands by 0.16-0.20 s (data README; default 0.18 s, the middle). A step of
dt is the exact arc ds = v dt, dtheta = w dt (numerics.motion, kappa = 1/2 with the
chord factor). The velocity errors are white noise whose average over the README's
window tau = 0.2 s has sigma_v = v0 + kv |v|, sigma_w = w0 + kw |w|; the step's noise is
then Q = diag(sigma_v^2, sigma_w^2) tau dt on (ds, dtheta) (variance proportional to dt).

**Landmarks.** z = (r, phi) of a known landmark (numerics.rangebearing, bearing
innovation wrapped with numerics.angles); sigma_r = max(r_min, k_r r_hat) (range-
proportional, at the predicted range so that an outlier cannot widen its own gate),
sigma_phi constant, plus the surveyed landmark position covariance through H_m.
Sigmas are the README's 95th percentiles / 1.96 (Gaussian core; the heavy tail is the
gate's job). Gate: NIS = nu^T S^-1 nu > chi2_2(p) = -2 ln(1 - p) (p = 0.999: 13.8) ->
the measurement is counted and named (``EkfTrack.gated``), not used.

**Robots.** Robot i measures (r, phi) to robot j. The peer's position enters as an
uncertain landmark: R' = R + H_m P_j[:2, :2] H_m^T. Estimates of i and j are correlated
after earlier exchanges, and the correlation is not tracked, so the update is a
covariance intersection (Julier & Uhlmann 1997) of i's prior with the information of
the measurement: P+^-1 = w P^-1 + (1 - w) H^T R'^-1 H, i.e. the Kalman update with
prior P / w and noise R' / (1 - w); w minimises det P+ (closed form below, default) or
trace P+. The fused estimate is consistent for any correlation, so nothing is counted
twice; each measurement is used once, by the robot that made it (the peer is not
updated). The gate uses S = H P H^T + R' (the innovation as if independent).

**Pure**: one deterministic pass over the merged, time-ordered stream of every robot's
odometry (shifted) and measurements; no threads, no clocks.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from localization.mrclam import MrclamRun, RobotRun
from numerics import ekf
from numerics.angles import wrap, wrap_angle
from numerics.motion import motion, motion_jacobians
from numerics.rangebearing import range_bearing


@dataclass(frozen=True)
class MrclamEkfConfig:
    """Noise model and filter settings (1-sigma; derivation in the module docstring
    and docs/algorithms.md). Defaults come from the data README's error percentiles
    (sigma = p95 / 1.96) and physical reasoning, never fitted to one run's score."""

    #: Commands act this much later than stamped (README: truth trails by 0.16-0.20 s).
    command_lag_s: float = 0.18
    #: Window over which the velocity sigmas below are defined (README: 0.2 s).
    noise_window_s: float = 0.2
    v_sigma_mps: float = 0.005
    v_sigma_rel: float = 0.2
    w_sigma_radps: float = 0.12 / 1.96
    w_sigma_rel: float = 0.0
    landmark_range_rel: float = 0.095 / 1.96
    landmark_bearing_rad: float = 0.027 / 1.96
    robot_range_rel: float = 0.078 / 1.96
    robot_bearing_rad: float = 0.026 / 1.96
    range_sigma_min_m: float = 0.02
    #: Chi-square gate probability (2 dof) for landmark and robot measurements.
    gate_probability: float = 0.999
    #: Covariance intersection weight: "det" or "trace" of the fused covariance.
    ci_criterion: str = "det"
    #: Initial sigma (x, y, theta) around the truth at the run's start.
    init_sigma: tuple[float, float, float] = (0.05, 0.05, 0.05)

    def __post_init__(self) -> None:
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f"gate_probability must be in (0, 1), got {self.gate_probability}")
        if self.ci_criterion not in ("det", "trace"):
            raise ValueError(f"ci_criterion must be 'det' or 'trace', got {self.ci_criterion!r}")
        if not self.noise_window_s > 0.0:
            raise ValueError(f"noise_window_s must be > 0, got {self.noise_window_s}")

    @property
    def gate(self) -> float:
        """chi2 quantile with 2 degrees of freedom: -2 ln(1 - p)."""
        return -2.0 * math.log1p(-self.gate_probability)


@dataclass
class EkfTrack:
    """One robot's EKF estimates, one row per event that touched it (its odometry
    samples, shifted by the lag, and its measurements), times on the data set's clock."""

    robot: int
    t: np.ndarray  # (n,) seconds
    mean: np.ndarray  # (n, 3) x, y, theta (theta continuous)
    cov: np.ndarray  # (n, 3, 3)
    counts: Counter = field(default_factory=Counter)
    #: The measurements the gate refused: (time, subject, NIS).
    gated: list[tuple[float, int, float]] = field(default_factory=list)

    def index_at(self, t: np.ndarray | float) -> np.ndarray:
        """Row of the latest estimate at or before each ``t`` (the first row before it)."""
        i = np.searchsorted(self.t, np.atleast_1d(np.asarray(t, float)), side="right") - 1
        return np.clip(i, 0, len(self.t) - 1)

    def sigma(self) -> np.ndarray:
        """(n, 3) standard deviations of x, y, theta."""
        return np.sqrt(np.maximum(np.diagonal(self.cov, axis1=1, axis2=2), 0.0))


def ci_weight(a: np.ndarray, r: np.ndarray, criterion: str = "det", p=None, h=None) -> float:
    """Covariance-intersection weight w in (0, 1] of the prior (1 = ignore the measurement).

    "det": with A = H P H^T and lambda_k the eigenvalues of R'^-1 A, det of the fused
    information is w det(P^-1) prod_k (lambda_k + w (1 - lambda_k)) (Sylvester), a
    log-concave function of w; its maximiser solves
    1/w + sum_k (1 - lambda_k) / (lambda_k + w (1 - lambda_k)) = 0, and is w = 1 when
    sum_k lambda_k <= 3. "trace": golden-section search of trace P+(w) (needs p, h).
    """
    if criterion == "trace":
        return _ci_weight_trace(p, h, r)
    lam = np.linalg.eigvals(np.linalg.solve(r, a)).real
    lam = np.maximum(lam, 0.0)
    if lam.sum() <= 3.0:
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(60):
        w = 0.5 * (lo + hi)
        g = 1.0 / w + sum((1.0 - lk) / (lk + w * (1.0 - lk)) for lk in lam)
        lo, hi = (w, hi) if g > 0.0 else (lo, w)
    return 0.5 * (lo + hi)


def _ci_posterior(p: np.ndarray, h: np.ndarray, r: np.ndarray, w: float) -> np.ndarray:
    y = w * np.linalg.inv(p) + (1.0 - w) * h.T @ np.linalg.solve(r, h)
    return np.linalg.inv(y)


def _ci_weight_trace(p: np.ndarray, h: np.ndarray, r: np.ndarray) -> float:
    lo, hi = 1e-3, 1.0
    g = (math.sqrt(5.0) - 1.0) / 2.0
    c, d = hi - g * (hi - lo), lo + g * (hi - lo)
    fc, fd = (np.trace(_ci_posterior(p, h, r, w)) for w in (c, d))
    for _ in range(40):
        if fc < fd:
            hi, d, fd = d, c, fc
            c = hi - g * (hi - lo)
            fc = np.trace(_ci_posterior(p, h, r, c))
        else:
            lo, c, fc = c, d, fd
            d = lo + g * (hi - lo)
            fd = np.trace(_ci_posterior(p, h, r, d))
    w = 0.5 * (lo + hi)
    return 1.0 if np.trace(p) <= np.trace(_ci_posterior(p, h, r, w)) else w


class _Filter:
    """One robot's EKF: state, covariance, held command and the time it stands at."""

    def __init__(self, s: np.ndarray, p: np.ndarray, t: float, cfg: MrclamEkfConfig) -> None:
        self.s, self.P, self.t, self.cfg = s, p, t, cfg
        self.v = 0.0
        self.w = 0.0

    def predict_to(self, t: float) -> None:
        dt = t - self.t
        if dt <= 0.0:
            return
        c = self.cfg
        u = np.array([self.v * dt, self.w * dt])
        f, g = motion_jacobians(self.s, u, 0.5, True)
        sv = c.v_sigma_mps + c.v_sigma_rel * abs(self.v)
        sw = c.w_sigma_radps + c.w_sigma_rel * abs(self.w)
        q = np.diag([sv * sv, sw * sw]) * (c.noise_window_s * dt)
        self.s = motion(self.s, u, 0.5, True)
        self.P = ekf.predict_covariance(self.P, f, g, q)
        self.t = t

    def update(
        self, z: np.ndarray, zhat: np.ndarray, h: np.ndarray, r: np.ndarray, gate: float, w=1.0
    ) -> tuple[bool, float]:
        """Gate on the NIS, then the (CI-weighted when w < 1) Joseph update."""
        nu = np.array([z[0] - zhat[0], wrap_angle(z[1] - zhat[1])])
        _, s_, s_inv = ekf.innovation(self.P, h, r)
        d2 = ekf.nis(nu, s_inv)
        if not d2 <= gate:
            return False, d2
        if w is None:  # covariance intersection, weight chosen here
            w = ci_weight(h @ self.P @ h.T, r, self.cfg.ci_criterion, self.P, h)
            if w >= 1.0:
                return True, d2
        p = self.P / w if w < 1.0 else self.P
        rr = r / (1.0 - w) if w < 1.0 else r
        ph, _, s_inv = ekf.innovation(p, h, rr)
        self.s, self.P = ekf.joseph_update(self.s, p, nu, h, rr, ph, s_inv)
        self.P = 0.5 * (self.P + self.P.T)
        return True, d2


def _events(run: MrclamRun, robots: list[int], lag: float) -> tuple[np.ndarray, np.ndarray]:
    """Merged stream: rows (time, kind, robot, a, b, c) sorted by (time, kind, robot),
    kind 0 = command (a = v, b = w), 1 = measurement (a = subject, b = r, c = phi)."""
    rows = []
    for n in robots:
        o = run.robots[n].odometry
        rows.append(
            np.column_stack(
                [o[:, 0] + lag, np.zeros(len(o)), np.full(len(o), n), o[:, 1:], 0 * o[:, 0]]
            )
        )
        m = run.robots[n].measurements
        rows.append(np.column_stack([m[:, 0], np.ones(len(m)), np.full(len(m), n), m[:, 1:]]))
    ev = np.concatenate(rows)
    order = np.lexsort((ev[:, 2], ev[:, 1], ev[:, 0]))
    return ev[order], order


def _initial(robot: RobotRun, t0: float, sigma) -> tuple[np.ndarray, np.ndarray]:
    pose, ok = robot.truth_at(t0)
    if not ok[0]:  # no truth at the start: the first truth sample after it
        k = int(np.searchsorted(robot.truth[:, 0], t0))
        pose = robot.truth[min(k, len(robot.truth) - 1), 1:][None]
    return pose[0].astype(float), np.diag(np.square(np.asarray(sigma, float)))


def run_ekf(
    run: MrclamRun,
    robots: list[int] | None = None,
    cooperative: bool = True,
    config: MrclamEkfConfig | None = None,
) -> dict[int, EkfTrack]:
    """EKF tracks of ``robots`` (default all) over the whole run; see the module doc.

    Every robot starts at the run's start, at the truth there with ``init_sigma``, at
    rest until its first command acts. Measurements of a subject that is neither a
    landmark of the map nor a robot being run, non-finite or non-positive ranges, and
    measurements stamped before the start are counted (``EkfTrack.counts``) and skipped.
    """
    cfg = config or MrclamEkfConfig()
    ids = sorted(run.robots) if robots is None else list(robots)
    for n in ids:
        if n not in run.robots:
            raise ValueError(f"robot {n} is not in {run.directory} (has {sorted(run.robots)})")
    t0 = run.start_s
    filters = {n: _Filter(*_initial(run.robots[n], t0, cfg.init_sigma), t0, cfg) for n in ids}
    ev, _ = _events(run, ids, cfg.command_lag_s)
    size = {n: 1 + int(np.sum(ev[:, 2] == n)) for n in ids}
    tt = {n: np.empty(size[n]) for n in ids}
    mm = {n: np.empty((size[n], 3)) for n in ids}
    cc = {n: np.empty((size[n], 3, 3)) for n in ids}
    k = dict.fromkeys(ids, 0)
    counts = {n: Counter() for n in ids}
    gated: dict[int, list] = {n: [] for n in ids}
    gate = cfg.gate

    def record(n: int) -> None:
        f, i = filters[n], k[n]
        tt[n][i], mm[n][i], cc[n][i] = f.t, f.s, f.P
        k[n] = i + 1

    for n in ids:
        record(n)
    for t, kind, rn, a, b, c in ev.tolist():
        n = int(rn)
        f = filters[n]
        if t < f.t:
            counts[n]["before_start"] += 1
            continue
        f.predict_to(t)
        if kind == 0.0:
            f.v, f.w = a, b
            counts[n]["odometry"] += 1
            record(n)
            continue
        subj = int(a)
        z = np.array([b, c])
        if not (math.isfinite(b) and math.isfinite(c) and b > 0.0):
            counts[n]["invalid"] += 1
        elif subj in run.landmarks:
            _landmark(f, subj, z, run.landmarks[subj], cfg, gate, counts[n], gated[n], t)
        elif subj in filters and subj != n:
            if not cooperative:
                counts[n]["robot_ignored"] += 1
            else:
                peer = filters[subj]
                peer.predict_to(t)
                _robot(f, peer, subj, z, cfg, gate, counts[n], gated[n], t)
        elif subj in run.robots:
            counts[n]["robot_not_run"] += 1
        else:
            counts[n]["unknown_subject"] += 1
        record(n)
    return {
        n: EkfTrack(n, tt[n][: k[n]], mm[n][: k[n]], cc[n][: k[n]], counts[n], gated[n])
        for n in ids
    }


def _landmark(f: _Filter, subj, z, mark, cfg, gate, counts, gated, t) -> None:
    zhat, hs, hm = range_bearing(f.s, mark[0], mark[1])
    if zhat[0] < 1e-6:
        counts["landmark_on_robot"] += 1
        return
    sr = max(cfg.range_sigma_min_m, cfg.landmark_range_rel * zhat[0])
    r = (
        np.diag([sr * sr, cfg.landmark_bearing_rad**2])
        + hm @ np.diag([mark[2] ** 2, mark[3] ** 2]) @ hm.T
    )
    ok, d2 = f.update(z, zhat, hs, r, gate)
    if ok:
        counts["landmark_accepted"] += 1
    else:
        counts["landmark_gated"] += 1
        gated.append((t, subj, d2))


def _robot(f: _Filter, peer: _Filter, subj, z, cfg, gate, counts, gated, t) -> None:
    zhat, hs, hm = range_bearing(f.s, peer.s[0], peer.s[1])
    if zhat[0] < 1e-6:
        counts["robot_on_robot"] += 1
        return
    sr = max(cfg.range_sigma_min_m, cfg.robot_range_rel * zhat[0])
    r = np.diag([sr * sr, cfg.robot_bearing_rad**2]) + hm @ peer.P[:2, :2] @ hm.T
    before = f.P
    ok, d2 = f.update(z, zhat, hs, r, gate, w=None)
    if not ok:
        counts["robot_gated"] += 1
        gated.append((t, subj, d2))
    elif f.P is before:
        counts["robot_no_gain"] += 1  # CI weight 1: the peer added nothing
    else:
        counts["robot_accepted"] += 1


def score_track(track: EkfTrack, robot: RobotRun, n_sigma: float = 3.0) -> dict:
    """RMSE and n-sigma containment against the truth at the track's own instants
    (the commands are shifted by the lag, so the track is on the truth's clock), only
    where the truth exists (``truth_at``'s mask). Containment: x, y and theta (wrapped)
    all within n_sigma standard deviations; ``containment_xy``: x and y only."""
    pose, ok = robot.truth_at(track.t)
    e = track.mean[ok] - pose[ok]
    e[:, 2] = wrap(e[:, 2])
    lim = n_sigma * track.sigma()[ok]
    inside = np.abs(e) <= lim
    n = int(ok.sum())
    return {
        "scored": n,
        "rmse_m": float(np.sqrt(np.mean(e[:, 0] ** 2 + e[:, 1] ** 2))) if n else math.nan,
        "heading_rmse_rad": float(np.sqrt(np.mean(e[:, 2] ** 2))) if n else math.nan,
        "containment": float(np.mean(inside.all(axis=1))) if n else math.nan,
        "containment_xy": float(np.mean(inside[:, :2].all(axis=1))) if n else math.nan,
    }
