"""EKF localization of ekf-vs-cp.txt eq. (3)-(4), for the comparison with CP, and the
integrity monitor the paper leaves as future work (run EKF and CP together).

State s = (x, y, theta) (theta kept continuous), input the wheel displacements
u = (dSr, dSl) with per-wheel noise sigma = abs + rel * |dS| (eq. (1)-(2) through
``localization.odometry``); measurements: GPS position (h = (x, y)) and a heading
(h = theta, e.g. the gyro's angle). Prediction ``P = A P A^T + W Q W^T``; update with
the Kalman gain, Joseph form for symmetry (both from numerics.ekf). The 3-sigma box the
paper compares with CP is ``mean +/- 3 sqrt(diag P)``.

Message-level API::

    ekf = EkfLocalizer(EkfConfig(...), initial=PoseEstimate | None)
    ekf.feed_odometry(RobotOdometry) / feed_gyro(GyroSample) / feed_gps(GpsFix)
        -> PoseEstimate | None
    ekf.estimate() -> PoseEstimate ; ekf.box(n_sigma=3) -> PoseBox

:class:`IntegrityMonitor` takes the EKF estimate and the CP box of the same step, flags
an integrity alarm when the estimate leaves the box, and offers the estimate clipped to
the box (a guaranteed-consistent point). :func:`integrity_counts` scores a whole EKF
track against a track of guaranteed boxes and the truth (alarms, false alarms, misses;
definitions in its docstring).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar, Protocol

import numpy as np

from localization.intake import MessageIntake
from localization.odometry import motion, motion_jacobians, wheels_from_poses
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
from msgs.stamps import SetBackGate
from numerics import ekf
from numerics.angles import wrap


@dataclass(frozen=True)
class EkfConfig:
    """Standard deviations (1 sigma) of the noises; defaults match CPConfig's bounds
    for uniform errors (sigma = bound / sqrt(3))."""

    wheelbase_m: float = 0.33
    wheel_sigma_abs_m: float = 0.0005 / math.sqrt(3.0)
    wheel_sigma_rel: float = 0.01 / math.sqrt(3.0)
    gps_sigma_m: float = 2.0 / math.sqrt(3.0)
    gyro_sigma_rad: float = math.radians(1.0) / math.sqrt(3.0)
    gyro_offset_rad: float = 0.0
    kappa: float = 0.5
    chord: bool = True
    init_sigma: tuple[float, float, float] = (10.0, 10.0, math.pi)
    min_gps_mode: int = 2


class EkfLocalizer(MessageIntake):
    """Extended Kalman filter on (x, y, theta); see the module docstring."""

    FEEDS: ClassVar[dict[type, str]] = {
        RobotOdometry: "feed_odometry",
        GyroSample: "feed_gyro",
        GpsFix: "feed_gps",
    }

    def __init__(
        self,
        config: EkfConfig | None = None,
        initial: PoseEstimate | None = None,
        source: str = "ekf",
    ) -> None:
        self.cfg = config or EkfConfig()
        self.source = source
        if initial is None:
            self.s = np.zeros(3)
            self.P = np.diag(np.square(self.cfg.init_sigma))
        else:
            self.s = np.array([initial.pose.x, initial.pose.y, initial.pose.theta])
            self.P = np.array(initial.covariance, dtype=float).reshape(3, 3)
        self.stamp_ns = 0 if initial is None else initial.stamp_ns
        self._last_odom: RobotOdometry | None = None
        self._set_back = SetBackGate()
        self.skipped: dict[str, int] = {}

    # ---------------------------------------------------------------- array level
    def predict(self, dsr: float, dsl: float) -> None:
        c = self.cfg
        u = np.array([dsr, dsl], dtype=float)
        a, w = motion_jacobians(self.s, u, c.wheelbase_m, c.kappa, c.chord)
        q = np.diag(np.square(c.wheel_sigma_abs_m + c.wheel_sigma_rel * np.abs(u)))
        self.s = motion(self.s, u, c.wheelbase_m, c.kappa, c.chord)
        self.P = ekf.predict_covariance(self.P, a, w, q)

    def _update(self, z: np.ndarray, h: np.ndarray, hx: np.ndarray, r: np.ndarray) -> float:
        """Linear-in-state update; returns the innovation's Mahalanobis distance^2."""
        y = z - hx
        ph, _, s_inv = ekf.innovation(self.P, h, r)
        self.s, self.P = ekf.joseph_update(self.s, self.P, y, h, r, ph, s_inv)
        return ekf.nis(y, s_inv)

    def update_gps(self, east: float, north: float, sigma: float | None = None) -> float:
        sg = self.cfg.gps_sigma_m if sigma is None else sigma
        h = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
        return self._update(np.array([east, north]), h, self.s[:2], np.eye(2) * sg * sg)

    def update_heading(self, theta: float, sigma: float | None = None) -> float:
        sg = self.cfg.gyro_sigma_rad if sigma is None else sigma
        # Innovation wrapped to (-pi, pi] about the continuous state.
        z = self.s[2] + wrap_angle(theta - self.s[2])
        h = np.array([[0.0, 0.0, 1.0]])
        return self._update(np.array([z]), h, self.s[2:], np.array([[sg * sg]]))

    def box_arrays(self, n_sigma: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
        r = n_sigma * np.sqrt(np.maximum(np.diag(self.P), 0.0))
        return self.s - r, self.s + r

    # ---------------------------------------------------------------- messages
    def estimate(self) -> PoseEstimate:
        x, y, th = self.s
        return PoseEstimate(
            stamp_ns=int(self.stamp_ns),
            pose=Pose2D(float(x), float(y), wrap_angle(float(th))),
            covariance=tuple(float(v) for v in self.P.ravel()),
            frame="map",
            source=self.source,
        )

    def box(self, n_sigma: float = 3.0, robot: str = "") -> PoseBox:
        lo, hi = self.box_arrays(n_sigma)
        k = round(self.s[2] / (2 * math.pi)) * 2 * math.pi
        return PoseBox(
            stamp_ns=int(self.stamp_ns),
            robot=robot,
            x=Interval(float(lo[0]), float(hi[0])),
            y=Interval(float(lo[1]), float(hi[1])),
            theta=Interval(float(lo[2] - k), float(hi[2] - k)),
        )

    def feed_odometry(self, odom: RobotOdometry) -> PoseEstimate | None:
        prev, self._last_odom = self._last_odom, odom
        if prev is None:
            self.stamp_ns = odom.stamp_ns
            return self.estimate()
        if odom.stamp_ns <= prev.stamp_ns:
            if self._set_back.older(odom.stamp_ns, prev.stamp_ns) == "confirmed":
                self._skip("odometry_clock_set_back")  # a new baseline
                return None
            self._last_odom = prev
            self._skip("odometry_out_of_order")  # late, or held: one more than a second back
            return None
        self._set_back.newer()
        c = self.cfg
        dsr, dsl = wheels_from_poses(prev.pose, odom.pose, c.wheelbase_m, c.kappa, c.chord)
        if not (math.isfinite(dsr) and math.isfinite(dsl)):
            self._skip("odometry_invalid")
            return None
        self.predict(dsr, dsl)
        self.stamp_ns = odom.stamp_ns
        return self.estimate()

    def feed_gyro(self, g: GyroSample) -> PoseEstimate | None:
        if not math.isfinite(g.angle_rad):
            self._skip("gyro_invalid")
            return None
        self.update_heading(g.angle_rad + self.cfg.gyro_offset_rad)
        self.stamp_ns = max(self.stamp_ns, g.stamp_ns)
        return self.estimate()

    def feed_gps(self, fix: GpsFix) -> PoseEstimate | None:
        en = self._gps_position(fix, self.cfg.min_gps_mode)
        if en is None:
            return None
        self.update_gps(*en)
        self.stamp_ns = max(self.stamp_ns, fix.stamp_ns)
        return self.estimate()


@dataclass(frozen=True)
class IntegrityReport:
    """One step of the EKF/CP integrity check."""

    stamp_ns: int
    inside: bool  # the EKF estimate lies in the CP box
    clipped: Pose2D  # the EKF estimate clipped to the CP box
    distance_m: float  # how far the EKF position is outside the box (0 if inside)


def _clip_angle(th: float, box: Interval) -> tuple[float, bool]:
    if box.empty or box.width >= 2 * math.pi:
        return th, True
    mid = 0.5 * (box.lo + box.hi)
    t = mid + wrap_angle(th - mid)
    inside = box.lo <= t <= box.hi
    return wrap_angle(min(max(t, box.lo), box.hi)), inside


@dataclass
class IntegrityMonitor:
    """Runs alongside EKF and CP: alarms when the EKF leaves the guaranteed box."""

    alarms: list[int] = field(default_factory=list)
    checks: int = 0

    def check(self, est: PoseEstimate, box: PoseBox) -> IntegrityReport:
        p = est.pose
        self.checks += 1
        if box.x.empty or box.y.empty:
            return IntegrityReport(est.stamp_ns, True, p, 0.0)
        cx = min(max(p.x, box.x.lo), box.x.hi)
        cy = min(max(p.y, box.y.lo), box.y.hi)
        th, th_in = _clip_angle(p.theta, box.theta)
        inside = box.x.contains(p.x) and box.y.contains(p.y) and th_in
        if not inside:
            self.alarms.append(est.stamp_ns)
        return IntegrityReport(
            est.stamp_ns, inside, Pose2D(cx, cy, th), math.hypot(p.x - cx, p.y - cy)
        )

    @property
    def alarm_rate(self) -> float:
        return len(self.alarms) / self.checks if self.checks else 0.0


class _Track(Protocol):
    t: np.ndarray  # (n,) seconds, non-decreasing
    mean: np.ndarray  # (n, 3) x, y, theta
    cov: np.ndarray  # (n, 3, 3)


@dataclass(frozen=True)
class BoxTrack:
    """Guaranteed boxes over time: ``t`` (m,), ``lo`` and ``hi`` (m, 3) of x, y, theta.
    A heading interval may lie on any 2 pi branch; one 2 pi wide or wider holds every
    heading. A box with lo > hi or a NaN in any component is empty."""

    t: np.ndarray
    lo: np.ndarray
    hi: np.ndarray


def _angles_in(th: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Angle th inside [lo, hi] modulo 2 pi."""
    half = 0.5 * (hi - lo)
    return (half >= math.pi) | (np.abs(wrap(th - 0.5 * (lo + hi))) <= half)


def _angles_meet(lo1, hi1, lo2, hi2) -> np.ndarray:
    """[lo1, hi1] and [lo2, hi2] share an angle modulo 2 pi (for widths < 2 pi, the
    wrapped distance of the centres is at most the sum of the half widths)."""
    h1, h2 = 0.5 * (hi1 - lo1), 0.5 * (hi2 - lo2)
    d = np.abs(wrap(0.5 * (lo1 + hi1) - 0.5 * (lo2 + hi2)))
    return (h1 >= math.pi) | (h2 >= math.pi) | (d <= h1 + h2)


def integrity_counts(
    track: _Track,
    boxes: BoxTrack,
    truth: tuple[np.ndarray, np.ndarray],
    n_sigma: float = 3.0,
) -> dict[str, int]:
    """Integrity of an EKF track against guaranteed (CP) boxes, scored with the truth.

    At every box instant t_k (boxes.t) the EKF is taken at its latest row at or before
    t_k (instants before its first row are counted as ``no_estimate`` and skipped; empty
    boxes as ``empty_boxes``). ``truth`` = (pose (m, 3), has_truth (m,)) at boxes.t, as
    ``RobotRun.truth_at(boxes.t)`` returns it. With E_k = the EKF's n-sigma region, the
    box mean +/- n_sigma sqrt(diag P) (heading modulo 2 pi), and B_k the CP box:

    - ``alarms``: E_k and B_k are disjoint (some component, heading modulo 2 pi): the
      EKF claims, at n sigma, a pose that the guaranteed box excludes.
    - ``estimate_alarms``: the EKF mean lies outside B_k (:class:`IntegrityMonitor`'s
      alarm; weaker: the mean may leave the box while E_k still overlaps it).
    - Where the truth exists (``scored`` instants): ``ekf_misses``: truth outside E_k;
      ``box_misses``: truth outside B_k; ``false_alarms``: an alarm while the truth was
      inside E_k (the EKF was right, so the box, disjoint from E_k, missed the truth);
      ``true_alarms``: an alarm while the truth was outside E_k; ``missed_alarms``: no
      alarm while the truth was outside E_k (an EKF failure the monitor did not see);
      ``estimate_false_alarms``: an estimate alarm while the truth was inside E_k.

    Every count is an integer number of box instants.
    """
    bt = np.asarray(boxes.t, float)
    lo, hi = np.asarray(boxes.lo, float), np.asarray(boxes.hi, float)
    pose, has = np.asarray(truth[0], float), np.asarray(truth[1], bool)
    if not (lo.shape == hi.shape == (len(bt), 3) and pose.shape == (len(bt), 3)):
        raise ValueError("boxes.lo, boxes.hi and the truth must be (m, 3) for m box instants")
    tt = np.asarray(track.t, float)
    i = np.searchsorted(tt, bt, side="right") - 1
    have = i >= 0
    empty = np.isnan(lo).any(axis=1) | np.isnan(hi).any(axis=1) | (lo > hi).any(axis=1)
    use = have & ~empty
    i = np.clip(i, 0, len(tt) - 1)
    m = np.asarray(track.mean, float)[i]
    r = n_sigma * np.sqrt(np.maximum(np.diagonal(np.asarray(track.cov, float)[i], 0, 1, 2), 0.0))
    elo, ehi = m - r, m + r
    meet = (
        (elo[:, 0] <= hi[:, 0])
        & (lo[:, 0] <= ehi[:, 0])
        & (elo[:, 1] <= hi[:, 1])
        & (lo[:, 1] <= ehi[:, 1])
        & _angles_meet(elo[:, 2], ehi[:, 2], lo[:, 2], hi[:, 2])
    )
    mean_in = (
        (lo[:, 0] <= m[:, 0])
        & (m[:, 0] <= hi[:, 0])
        & (lo[:, 1] <= m[:, 1])
        & (m[:, 1] <= hi[:, 1])
        & _angles_in(m[:, 2], lo[:, 2], hi[:, 2])
    )
    ekf_ok = (np.abs(pose[:, :2] - m[:, :2]) <= r[:, :2]).all(axis=1) & (
        np.abs(wrap(pose[:, 2] - m[:, 2])) <= r[:, 2]
    )
    box_ok = (
        (lo[:, :2] <= pose[:, :2]).all(axis=1)
        & (pose[:, :2] <= hi[:, :2]).all(axis=1)
        & _angles_in(pose[:, 2], lo[:, 2], hi[:, 2])
    )
    alarm, est_alarm, scored = use & ~meet, use & ~mean_in, use & has

    def n(a: np.ndarray) -> int:
        return int(np.count_nonzero(a))

    return {
        "checked": n(use),
        "no_estimate": n(~have),
        "empty_boxes": n(have & empty),
        "scored": n(scored),
        "alarms": n(alarm),
        "estimate_alarms": n(est_alarm),
        "false_alarms": n(scored & alarm & ekf_ok),
        "true_alarms": n(scored & alarm & ~ekf_ok),
        "missed_alarms": n(scored & ~alarm & ~ekf_ok),
        "estimate_false_alarms": n(scored & est_alarm & ekf_ok),
        "ekf_misses": n(scored & ~ekf_ok),
        "box_misses": n(scored & ~box_ok),
    }
