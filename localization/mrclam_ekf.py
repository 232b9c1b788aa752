"""EKF localization of the MRCLAM robots (real data), alone or cooperative, for the
comparison with CP (issue 14 item 4). Every model and default is derived in
docs/algorithms.md ("EKF on the MRCLAM robots"); in short:

**State and motion.** One filter per robot on (x, y, theta, k, b): the pose (theta
continuous), a speed scale error and a turn-rate bias (Gauss-Markov; the motion model
and its Jacobians are localization/mrclam_motion.py). The odometry is the commanded
(v, w), held between samples and applied ``command_lag_s`` = 0.18 s after its stamp
(README: the truth trails the commands by 0.16-0.20 s; the camera is on the truth's
clock). White velocity errors whose average over ``noise_window_s`` has sigma
v0 + kv |v| and w0 + kw |w| give Q = diag(sigma_v^2, sigma_w^2) window / dt on the
velocities averaged over a step of dt, so the pose noise grows in proportion to dt.

**Landmarks.** z = (r, phi), numerics.rangebearing, bearing innovation wrapped with
numerics.angles; range sigma proportional to the predicted range, bearing sigma
constant (README p95 / 1.96), plus the surveyed landmark covariance. The camera's
errors are correlated in time and across landmarks: R is inflated by the AR(1) factor
(1 + rho) / (1 - rho), rho = exp(-dt / tau), dt the time since the robot's last used
measurement. Gate: NIS with the uninflated R above chi2_2(p) = -2 ln(1 - p)
(p = 0.999: 13.8) -> counted and named (``EkfTrack.gated``), not used.

**Robots.** Robot i measures (r, phi) to robot j; j's position enters as an uncertain
landmark. The correlation between the two estimates is not tracked, so both sides are
covariance intersections (localization/covariance_intersection.py) from the priors:
i with R + H_j P_j H_j^T, j (``peer_update = "both"``) with R + H_i P_i H_i^T. CI is
consistent for any correlation, so nothing is counted twice.

**Pure**: one deterministic pass over the merged, time-ordered stream of every robot's
odometry (shifted) and measurements; no threads, no clocks. The track has a row every
``output_period_s`` (the filter predicted to that instant) and one after every update.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np

from localization.covariance_intersection import ci_update, ci_weight
from localization.mrclam import MrclamRun, RobotRun
from localization.mrclam_motion import NX, biased_motion
from localization.mrclam_track import EkfTrack, score_track
from numerics import ekf
from numerics.angles import wrap_angle
from numerics.rangebearing import range_bearing

__all__ = ["EkfTrack", "MrclamEkfConfig", "ar1_inflation", "run_ekf", "score_track"]


@dataclass(frozen=True)
class MrclamEkfConfig:
    """Noise model and filter settings (1-sigma). Every default is derived in
    docs/algorithms.md from the data README's error percentiles and the same
    statistics over longer windows (sigma = p95 / 1.96), never fitted to a score."""

    #: Commands act this much later than stamped (README: truth trails by 0.16-0.20 s).
    command_lag_s: float = 0.18
    #: Window over which the white velocity sigmas below are defined (their intensity
    #: is sigma^2 * window); derived from the drift over 5-40 s windows.
    noise_window_s: float = 10.0
    #: sigma of the window-averaged forward velocity: v0 + kv |v| (m/s).
    v_sigma_mps: float = 0.0037
    v_sigma_rel: float = 0.028
    #: sigma of the window-averaged angular velocity: w0 + kw |w| (rad/s).
    w_sigma_radps: float = 0.0094
    w_sigma_rel: float = 0.0
    #: Stationary sigma of the speed scale error k and of the turn-rate bias b, and
    #: their correlation time (Gauss-Markov states; 0 sigmas give a 3-state EKF).
    speed_scale_sigma: float = 0.031
    turn_bias_sigma_radps: float = 0.0056
    bias_tau_s: float = 120.0
    #: Landmark range sigma = rel * predicted range (README p95 / 1.96), bearing sigma.
    landmark_range_rel: float = 0.095 / 1.96
    landmark_bearing_rad: float = 0.027 / 1.96
    robot_range_rel: float = 0.078 / 1.96
    robot_bearing_rad: float = 0.026 / 1.96
    range_sigma_min_m: float = 0.02
    #: Correlation time of a robot's measurement errors (AR(1) variance inflation).
    error_correlation_s: float = 7.0
    #: "robot": one error process per robot (all subjects); "subject": per subject.
    correlation_scope: str = "robot"
    #: Measurements of one robot less than frame_gap_s apart are one camera frame; the
    #: AR(1) clock runs from frame to frame, and within a frame of m measurements the
    #: range and bearing variances are multiplied by 1 + (m - 1) rho (equicorrelated
    #: errors; rho measured across landmarks at zero lag: 0.22 range, 0.56 bearing).
    frame_gap_s: float = 0.01
    frame_correlation: tuple[float, float] = (0.22, 0.56)
    #: Chi-square gate probability (2 dof) for landmark and robot measurements.
    gate_probability: float = 0.999
    #: Covariance intersection weight: minimise "det" or "trace" of the fused covariance.
    ci_criterion: str = "det"
    #: "observer": a robot-robot measurement updates its observer only; "both": the
    #: observed robot as well (each side a CI update from the other's prior).
    peer_update: str = "both"
    #: The track has a row every output_period_s from the run's start (on_grid), and
    #: one after every measurement update of the robot.
    output_period_s: float = 0.05
    #: Initial sigma (x, y, theta) around the truth at the run's start.
    init_sigma: tuple[float, float, float] = (0.05, 0.05, 0.05)

    def __post_init__(self) -> None:
        if not 0.0 < self.gate_probability < 1.0:
            raise ValueError(f"gate_probability must be in (0, 1), got {self.gate_probability}")
        if self.ci_criterion not in ("det", "trace"):
            raise ValueError(f"ci_criterion must be 'det' or 'trace', got {self.ci_criterion!r}")
        if self.correlation_scope not in ("robot", "subject"):
            raise ValueError(
                f"correlation_scope must be 'robot' or 'subject', got {self.correlation_scope!r}"
            )
        if self.peer_update not in ("observer", "both"):
            raise ValueError(f"peer_update must be 'observer' or 'both', got {self.peer_update!r}")
        if not self.output_period_s > 0.0:
            raise ValueError(f"output_period_s must be > 0, got {self.output_period_s}")
        if not self.noise_window_s > 0.0:
            raise ValueError(f"noise_window_s must be > 0, got {self.noise_window_s}")

    @property
    def gate(self) -> float:
        """chi2 quantile with 2 degrees of freedom: -2 ln(1 - p)."""
        return -2.0 * math.log1p(-self.gate_probability)


def ar1_inflation(dt: float, tau: float) -> float:
    """(1 + rho) / (1 - rho) with rho = exp(-dt / tau): the variance factor under which
    errors of an AR(1) process sampled every dt carry, summed, the information they
    really hold (the long-run variance of their mean); 1 for tau <= 0 or the first."""
    if tau <= 0.0 or not dt < math.inf:
        return 1.0
    rho = math.exp(-max(dt, 1e-9) / tau)
    return (1.0 + rho) / (1.0 - rho)


class _Filter:
    """One robot's EKF on (x, y, theta, k, b) (localization/mrclam_motion.py): state,
    covariance, held command and the time it stands at."""

    def __init__(self, s: np.ndarray, p: np.ndarray, t: float, cfg: MrclamEkfConfig) -> None:
        self.s = np.zeros(NX)
        self.s[:3] = s
        self.P = np.zeros((NX, NX))
        self.P[:3, :3] = p
        self.P[3, 3] = cfg.speed_scale_sigma**2
        self.P[4, 4] = cfg.turn_bias_sigma_radps**2
        self.t, self.cfg = t, cfg
        self.v = 0.0
        self.w = 0.0

    def predict_to(self, t: float) -> None:
        """Integrate the held command (v, w) from the filter's time to ``t``:
        P' = F P F^T + G Q G^T + Q_bias, Q = diag(sigma_v^2, sigma_w^2) tau / dt (the
        variance of white velocity errors averaged over dt: G Q G^T grows with dt) and
        Q_bias = diag(sigma_k^2, sigma_b^2) (1 - a^2), the Gauss-Markov driving noise."""
        dt = t - self.t
        if dt <= 0.0:
            return
        c = self.cfg
        s, f, g = biased_motion(self.s, self.v, self.w, dt, c.bias_tau_s)
        sv = c.v_sigma_mps + c.v_sigma_rel * abs(self.v)
        sw = c.w_sigma_radps + c.w_sigma_rel * abs(self.w)
        p = ekf.predict_covariance(
            self.P, f, g, np.diag([sv * sv, sw * sw]) * (c.noise_window_s / dt)
        )
        a2 = f[3, 3] ** 2
        p[3, 3] += c.speed_scale_sigma**2 * (1.0 - a2)
        p[4, 4] += c.turn_bias_sigma_radps**2 * (1.0 - a2)
        self.s, self.P, self.t = s, p, t


def _pad(h: np.ndarray) -> np.ndarray:
    """A measurement Jacobian on the pose (2 x 3 or 2 x 2) on the whole state (2 x NX)."""
    out = np.zeros((h.shape[0], NX))
    out[:, : h.shape[1]] = h
    return out


def _innovation(z: np.ndarray, zhat: np.ndarray) -> np.ndarray:
    return np.array([z[0] - zhat[0], wrap_angle(z[1] - zhat[1])])


def _events(run: MrclamRun, robots: list[int], lag: float, gap: float) -> np.ndarray:
    """Merged stream: rows (time, kind, robot, a, b, c, frame time, frame size) sorted
    by (time, kind, robot, file order), kind 0 = command (a = v, b = w), 1 = measurement
    (a = subject, b = r, c = phi; its camera frame: the measurements of the robot less
    than ``gap`` apart). Commands are stamped ``lag`` later than in the file."""
    rows = []
    for n in robots:
        o = run.robots[n].odometry
        z = np.zeros(len(o))
        rows.append(np.column_stack([o[:, 0] + lag, z, z + n, o[:, 1:], z, z, z]))
        m = run.robots[n].measurements
        start = np.concatenate([[True], np.diff(m[:, 0]) > gap]) if len(m) else np.zeros(0, bool)
        frame = np.cumsum(start) - 1
        ft = m[start, 0][frame] if len(m) else np.zeros(0)
        size = np.bincount(frame)[frame] if len(m) else np.zeros(0)
        one = np.ones(len(m))
        rows.append(np.column_stack([m[:, 0], one, one * n, m[:, 1:], ft, size]))
    ev = np.concatenate(rows)
    return ev[np.lexsort((ev[:, 2], ev[:, 1], ev[:, 0]))]


def _initial(robot: RobotRun, t0: float, sigma) -> tuple[np.ndarray, np.ndarray]:
    pose, ok = robot.truth_at(t0)
    if not ok[0]:  # no truth at the start: the first truth sample after it
        k = int(np.searchsorted(robot.truth[:, 0], t0))
        pose = robot.truth[min(k, len(robot.truth) - 1), 1:][None]
    return pose[0].astype(float), np.diag(np.square(np.asarray(sigma, float)))


class _Run:
    """The filters of one run_ekf call, their recorded tracks and counts."""

    def __init__(self, run: MrclamRun, ids: list[int], cfg: MrclamEkfConfig, n_events) -> None:
        t0 = run.start_s
        self.cfg, self.marks, self.gate = cfg, run.landmarks, cfg.gate
        self.f = {n: _Filter(*_initial(run.robots[n], t0, cfg.init_sigma), t0, cfg) for n in ids}
        size = {n: 16 + n_events[n] // 2 for n in ids}
        self.tt = {n: np.empty(size[n]) for n in ids}
        self.mm = {n: np.empty((size[n], 3)) for n in ids}
        self.cc = {n: np.empty((size[n], 3, 3)) for n in ids}
        self.k = dict.fromkeys(ids, 0)
        self.grid = {n: np.zeros(size[n], bool) for n in ids}
        self.t0, self.next = t0, dict.fromkeys(ids, 1)
        self.counts = {n: Counter() for n in ids}
        self.gated: dict[int, list] = {n: [] for n in ids}
        self.last: dict[tuple[int, int], tuple[float, float]] = {}  # (frame time, its dt)
        for n in ids:
            self.record(n, True)

    def record(self, n: int, grid: bool = False) -> None:
        f, i = self.f[n], self.k[n]
        if i == len(self.tt[n]):  # grow (the grid's size depends on the run's length)
            for d in (self.tt, self.mm, self.cc, self.grid):
                d[n] = np.concatenate([d[n], np.zeros_like(d[n])])
        self.tt[n][i], self.mm[n][i], self.cc[n][i] = f.t, f.s[:3], f.P[:3, :3]
        self.grid[n][i] = grid
        self.k[n] = i + 1

    def advance(self, n: int, t: float) -> None:
        """Predict robot n through the grid instants up to ``t``, a row at each."""
        period, f = self.cfg.output_period_s, self.f[n]
        while (tg := self.t0 + self.next[n] * period) <= t:
            f.predict_to(tg)
            self.record(n, True)
            self.next[n] += 1

    def tracks(self) -> dict[int, EkfTrack]:
        return {
            n: EkfTrack(
                n,
                self.tt[n][:k],
                self.mm[n][:k],
                self.cc[n][:k],
                self.counts[n],
                self.gated[n],
                self.grid[n][:k],
            )
            for n, k in self.k.items()
        }

    def _key(self, n: int, subj: int) -> tuple[int, int]:
        return (n, subj if self.cfg.correlation_scope == "subject" else 0)

    def _r(self, n, subj, frame, rel: float, bearing: float, r_hat: float):
        """(R, R inflated, AR(1) dt) of a measurement of robot n in ``frame`` = (time,
        size): range sigma proportional to the predicted range; the variances inflated by
        the AR(1) factor of the time since the last frame used (of any subject or of this
        one, by scope) and, within a frame of m, by 1 + (m - 1) rho (see the config)."""
        key = self._key(n, subj)
        ft, size = frame
        last = self.last.get(key)
        dt = math.inf if last is None else (last[1] if last[0] == ft else ft - last[0])
        sr = max(self.cfg.range_sigma_min_m, rel * r_hat)
        var = np.array([sr * sr, bearing * bearing])
        m = size if self.cfg.correlation_scope == "robot" else 1.0
        infl = ar1_inflation(dt, self.cfg.error_correlation_s) * (
            1.0 + (m - 1.0) * np.asarray(self.cfg.frame_correlation)
        )
        return np.diag(var), np.diag(var * infl), dt

    def _used(self, n: int, subj: int, frame, dt: float) -> None:
        self.last[self._key(n, subj)] = (frame[0], dt)

    def landmark(self, n: int, t: float, subj: int, z: np.ndarray, frame) -> None:
        f, mark, cfg = self.f[n], self.marks[subj], self.cfg
        zhat, hs, hm = range_bearing(f.s, mark[0], mark[1])
        if zhat[0] < 1e-6:
            self.counts[n]["landmark_on_robot"] += 1
            return
        hs = _pad(hs)
        r, ri, dt = self._r(
            n, subj, frame, cfg.landmark_range_rel, cfg.landmark_bearing_rad, zhat[0]
        )
        rm = hm @ np.diag([mark[2] ** 2, mark[3] ** 2]) @ hm.T  # the surveyed position
        nu = _innovation(z, zhat)
        # Gate on the measurement's own (marginal) noise; update with the inflated one.
        d2 = ekf.nis(nu, np.linalg.inv(hs @ f.P @ hs.T + r + rm))
        if not d2 <= self.gate:
            self.counts[n]["landmark_gated"] += 1
            self.gated[n].append((t, subj, d2))
            return
        r = ri + rm
        ph, _, s_inv = ekf.innovation(f.P, hs, r)
        f.s, f.P = ekf.joseph_update(f.s, f.P, nu, hs, r, ph, s_inv)
        f.P = 0.5 * (f.P + f.P.T)
        self._used(n, subj, frame, dt)
        self.counts[n]["landmark_accepted"] += 1

    def robot(self, n: int, t: float, subj: int, z: np.ndarray, frame) -> None:
        """Robot n measured robot subj: CI update of n (and of subj, peer_update "both"),
        both from the priors, so the measurement enters each side once."""
        f, peer, cfg = self.f[n], self.f[subj], self.cfg
        self.advance(subj, t)
        peer.predict_to(t)
        zhat, hs, hm = range_bearing(f.s, peer.s[0], peer.s[1])
        if zhat[0] < 1e-6:
            self.counts[n]["robot_on_robot"] += 1
            return
        hs = _pad(hs)
        r, ri, dt = self._r(n, subj, frame, cfg.robot_range_rel, cfg.robot_bearing_rad, zhat[0])
        hp = _pad(hm)  # d(r, phi) / d(peer state): position only
        a_obs = hs @ f.P @ hs.T  # n's uncertainty, seen in the measurement
        a_peer = hp @ peer.P @ hp.T  # the peer's
        nu = _innovation(z, zhat)
        d2 = ekf.nis(nu, np.linalg.inv(a_obs + a_peer + r))
        if not d2 <= self.gate:
            self.counts[n]["robot_gated"] += 1
            self.gated[n].append((t, subj, d2))
            return
        r_obs = ri + a_peer
        r_peer = ri + a_obs
        w = ci_weight(f.P, hs, r_obs, cfg.ci_criterion, block=3)
        f.s, f.P = ci_update(f.s, f.P, nu, hs, r_obs, w)
        self.counts[n]["robot_accepted" if w < 1.0 else "robot_no_gain"] += 1
        if cfg.peer_update == "both":
            wp = ci_weight(peer.P, hp, r_peer, cfg.ci_criterion, block=3)
            peer.s, peer.P = ci_update(peer.s, peer.P, nu, hp, r_peer, wp)
            self.counts[subj]["seen_accepted" if wp < 1.0 else "seen_no_gain"] += 1
            if wp < 1.0:
                self.record(subj)
        self._used(n, subj, frame, dt)


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
    measurements stamped before the start are counted (``EkfTrack.counts``) and skipped;
    so are robot-robot measurements when ``cooperative`` is False.
    """
    cfg = config or MrclamEkfConfig()
    ids = sorted(run.robots) if robots is None else list(dict.fromkeys(robots))
    for n in ids:
        if n not in run.robots:
            raise ValueError(f"robot {n} is not in {run.directory} (has {sorted(run.robots)})")
    ev = _events(run, ids, cfg.command_lag_s, cfg.frame_gap_s)
    st = _Run(run, ids, cfg, {n: int(np.sum(ev[:, 2] == n)) for n in ids})
    for t, kind, rn, a, b, c, ft, fm in ev.tolist():
        n = int(rn)
        f, counts = st.f[n], st.counts[n]
        if t < run.start_s:
            counts["before_start"] += 1
            continue
        st.advance(n, t)
        if kind == 0.0:
            counts["odometry"] += 1
            if a != f.v or b != f.w:  # a new command: the old one acts until now
                f.predict_to(t)
                f.v, f.w = a, b
            continue
        f.predict_to(t)
        if not (math.isfinite(b) and math.isfinite(c) and b > 0.0):
            counts["invalid"] += 1
            continue
        if int(a) in run.landmarks:
            st.landmark(n, t, int(a), np.array([b, c]), (ft, fm))
        elif int(a) in st.f and int(a) != n:
            if cooperative:
                st.robot(n, t, int(a), np.array([b, c]), (ft, fm))
            else:
                counts["robot_ignored"] += 1
        elif int(a) in run.robots:
            counts["robot_not_run"] += 1
        else:
            counts["unknown_subject"] += 1
        st.record(n)
    end = float(ev[-1, 0]) if len(ev) else run.start_s
    for n in ids:
        st.advance(n, end)
    return st.tracks()
