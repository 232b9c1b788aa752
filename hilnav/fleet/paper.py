"""One robot of the paper's experiment (ekf-vs-cp.txt §2.4) with its three localizers:
EKF (3-sigma box), single CP (own sensors) and multiple CP (also the peers' boxes and
range-bearing measurements), plus the integrity monitor. Used by bench/cooperative_cp.py
(all robots in one process) and by ``hilnav fleet`` (one process per robot, over Zenoh),
so both print the same figures.

The robot's own devices produce messages (RobotOdometry from the encoders, GyroSample,
GpsFix in local metres, RelativeMeasurement to each peer); the localizers are fed through
their message-level APIs, exactly as the daemon's pipeline feeds them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fakes.world.paper_scenario import Scenario
from localization.cp import CPConfig, CPLocalizer
from localization.ekf import EkfConfig, EkfLocalizer, IntegrityMonitor
from localization.odometry import motion
from msgs import (
    GpsFix,
    GyroSample,
    Interval,
    Pose2D,
    PoseBox,
    PoseEstimate,
    RelativeMeasurement,
    RobotOdometry,
)

METHODS = ("ekf", "single_cp", "multi_cp")


def cp_config(sc: Scenario, window: int = 40, outliers: int = 0) -> CPConfig:
    b = sc.bounds
    return CPConfig(
        wheelbase_m=sc.wheelbase_m,
        wheel_abs_bound_m=b.wheel_abs_m,
        wheel_rel_bound=b.wheel_rel,
        gps_bound_m=b.gps_m,
        gyro_bound_rad=b.gyro_rad,
        window=window,
        gps_outliers=outliers,
        speed_bound_mps=1.5,
        yaw_rate_bound_radps=1.0,
    )


def ekf_config(sc: Scenario) -> EkfConfig:
    """Standard deviations matching the uniform bounded errors (bound / sqrt 3)."""
    b, r3 = sc.bounds, math.sqrt(3.0)
    return EkfConfig(
        wheelbase_m=sc.wheelbase_m,
        wheel_sigma_abs_m=b.wheel_abs_m / r3,
        wheel_sigma_rel=b.wheel_rel / r3,
        gps_sigma_m=b.gps_m / r3,
        gyro_sigma_rad=b.gyro_rad / r3,
    )


@dataclass
class Track:
    """Per-step record of one method: box bounds and truth (for the figures)."""

    lo: list[np.ndarray] = field(default_factory=list)
    hi: list[np.ndarray] = field(default_factory=list)
    area_m2: list[float] = field(default_factory=list)
    contained: list[bool] = field(default_factory=list)


class PaperRobot:
    """Robot ``index`` of the scenario: its devices' messages and its localizers."""

    def __init__(self, sc: Scenario, index: int, *, window: int = 40, outliers: int = 0) -> None:
        self.sc, self.i = sc, index
        self.name = sc.names[index]
        b = sc.bounds
        g0 = sc.gps[index, 0]
        init = PoseBox(
            0,
            self.name,
            Interval(g0[0] - b.gps_m, g0[0] + b.gps_m),
            Interval(g0[1] - b.gps_m, g0[1] + b.gps_m),
            Interval(sc.gyro[index, 0] - b.gyro_rad, sc.gyro[index, 0] + b.gyro_rad),
        )
        cov = np.diag([b.gps_m**2 / 3, b.gps_m**2 / 3, b.gyro_rad**2 / 3])
        ekf_init = PoseEstimate(0, Pose2D(g0[0], g0[1], sc.gyro[index, 0]), tuple(cov.ravel()))
        self.ekf = EkfLocalizer(ekf_config(sc), initial=ekf_init, source=f"{self.name}/ekf")
        self.single = CPLocalizer(cp_config(sc, window, outliers), self.name, init)
        self.multi = CPLocalizer(cp_config(sc, window, outliers), self.name, init)
        self.monitor = IntegrityMonitor()
        self.tracks = {m: Track() for m in METHODS}
        self.truth: list[np.ndarray] = []
        self._odo = Pose2D(0.0, 0.0, 0.0)  # encoder odometry in the odom frame

    # ------------------------------------------------------------- devices
    def own_messages(self, s: int) -> list[tuple[str, object]]:
        """(topic, msg) of step ``s``: odometry, gyro, gps (if a fix)."""
        sc, i = self.sc, self.i
        st = int(sc.stamps_ns[s])
        if s:
            p = motion(
                np.array([self._odo.x, self._odo.y, self._odo.theta]),
                (sc.dsr[i, s], sc.dsl[i, s]),
                sc.wheelbase_m,
            )
            self._odo = Pose2D(float(p[0]), float(p[1]), float(p[2]))
        dt = sc.dt
        vr, vl = sc.dsr[i, s] / dt, sc.dsl[i, s] / dt
        out: list[tuple[str, object]] = [
            (
                "odometry",
                RobotOdometry(
                    st,
                    self._odo,
                    float(vl),
                    float(vr),
                    float(0.5 * (vl + vr)),
                    float((vr - vl) / sc.wheelbase_m),
                    12.5,
                    True,
                    True,
                ),
            ),
            ("gyro", GyroSample(st, float((vr - vl) / sc.wheelbase_m), float(sc.gyro[i, s]))),
        ]
        if not np.isnan(sc.gps[i, s, 0]):
            e, n = (float(v) for v in sc.gps[i, s])
            out.append(("gps", GpsFix(st, mode=3, quality=1, east_m=e, north_m=n)))
        return out

    def relative_messages(self, s: int, targets: list[str]) -> list[RelativeMeasurement]:
        sc, i, b = self.sc, self.i, self.sc.bounds
        st = int(sc.stamps_ns[s])
        out = []
        for t in targets:
            j = sc.names.index(t)
            out.append(
                RelativeMeasurement(
                    st,
                    self.name,
                    t,
                    float(sc.rel_range[i, j, s]),
                    float(sc.rel_bearing[i, j, s]),
                    b.range_m,
                    b.bearing_rad,
                )
            )
        return out

    # ------------------------------------------------------------- localizers
    def feed_own(self, msgs: list[tuple[str, object]]) -> None:
        for _, m in msgs:
            self.ekf.feed(m)
            self.single.feed(m)
            self.multi.feed(m)

    def feed_peer_box(self, box: PoseBox) -> None:
        self.multi.feed_peer_box(box)

    def cooperate(self, rels: list[RelativeMeasurement]) -> None:
        if rels:
            self.multi.feed_relatives(rels)

    def box(self) -> PoseBox:
        return self.multi.box()

    def record(self, s: int) -> None:
        """Score step ``s`` of every method against the truth."""
        t = self.sc.truth[self.i, s]
        self.truth.append(t)
        lo, hi = self.ekf.box_arrays(3.0)
        self._rec("ekf", lo, hi, t)
        for name, cp in (("single_cp", self.single), ("multi_cp", self.multi)):
            x, y, th = cp.current()
            lo = np.array([float(x.lo), float(y.lo), float(th.lo)])
            hi = np.array([float(x.hi), float(y.hi), float(th.hi)])
            self._rec(name, lo, hi, t)
        self.monitor.check(self.ekf.estimate(), self.multi.box())

    def _rec(self, name: str, lo: np.ndarray, hi: np.ndarray, t: np.ndarray) -> None:
        tr = self.tracks[name]
        # Headings are compared modulo 2*pi (the boxes keep theta continuous).
        k = np.round((0.5 * (lo[2] + hi[2]) - t[2]) / (2 * math.pi))
        tt = np.array([t[0], t[1], t[2] + 2 * math.pi * k])
        tr.lo.append(lo)
        tr.hi.append(hi)
        tr.area_m2.append(float((hi[0] - lo[0]) * (hi[1] - lo[1])))
        tr.contained.append(bool(np.all((lo <= tt) & (tt <= hi))))


def summary(robots: list[PaperRobot], dt: float) -> dict[str, float | int | str]:
    """The benchmark's figures over all robots (areas summed, containment pooled)."""
    out: dict[str, float | int | str] = {}
    for m in METHODS:
        area = sum(float(np.sum(r.tracks[m].area_m2)) * dt for r in robots)
        cont = [c for r in robots for c in r.tracks[m].contained]
        out[f"{m}_area"] = round(area, 4)
        out[f"{m}_containment"] = round(float(np.mean(cont)) if cont else 0.0, 4)
        half = [a for r in robots for a in r.tracks[m].area_m2[len(r.tracks[m].area_m2) // 2 :]]
        out[f"{m}_late_mean_area_m2"] = round(float(np.mean(half)) if half else 0.0, 5)
    if out["ekf_area"]:
        out["multi_over_ekf_area"] = round(float(out["multi_cp_area"]) / float(out["ekf_area"]), 4)
    out["integrity_alarms"] = sum(len(r.monitor.alarms) for r in robots)
    out["gps_dropped"] = sum(len(r.multi.dropped_gps) for r in robots)
    return out
