"""The paper's multi-robot experiment (ekf-vs-cp.txt §2.4) as devices, localizers and a
fleet scenario.

- :class:`PaperDevices`: robot ``i``'s simulated devices (fakes.world.paper_scenario) as
  messages: GyroSample, GpsFix in local metres and RobotOdometry from the encoders, in
  that arrival order per step, and one RelativeScan of the other robots;
- :class:`PaperRobot`: the paper's three localizers (EKF, single CP, multiple CP) and
  the integrity monitor fed those messages in one process (bench/cooperative_cp.py);
- :class:`PaperReference`: the comparison of ``hilnav fleet``: the paper's EKF and the
  robot's own CP service fed its own sensors only (single CP), beside the runtime's
  cooperative CP;
- :class:`PaperScenario`: the scenario ``paper`` of ``hilnav fleet``: N robots, each a
  :class:`hilnav.runtime.RobotRuntime` whose config (:meth:`PaperScenario.config`) runs
  the CP localization service with the scenario's error bounds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from fakes.world.paper_scenario import Scenario, paper_robots, simulate
from hilnav.config import RobotConfig, config_data, parse_config
from hilnav.fleet.score import METHODS, Track, pooled
from hilnav.services import LocalizationAdapter
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
    RelativeScan,
    RobotOdometry,
)

__all__ = ["METHODS", "PaperDevices", "PaperReference", "PaperRobot", "PaperScenario", "summary"]


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


def paper_ekf(sc: Scenario, i: int, base_ns: int = 0) -> EkfLocalizer:
    """The paper's EKF of robot ``i``, started at its first GPS fix and gyro heading."""
    b, g0 = sc.bounds, sc.gps[i, 0]
    cov = np.diag([b.gps_m**2 / 3, b.gps_m**2 / 3, b.gyro_rad**2 / 3])
    init = PoseEstimate(base_ns, Pose2D(g0[0], g0[1], sc.gyro[i, 0]), tuple(cov.ravel()))
    return EkfLocalizer(ekf_config(sc), initial=init, source=f"{sc.names[i]}/ekf")


class PaperDevices:
    """Robot ``index``'s devices as messages, stamped ``base_ns`` + scenario time."""

    def __init__(self, sc: Scenario, index: int, base_ns: int = 0) -> None:
        self.sc, self.i, self.base_ns = sc, index, int(base_ns)
        self.name = sc.names[index]
        self._odo = Pose2D(0.0, 0.0, 0.0)  # encoder odometry in the odom frame
        self._next = 0

    def stamp_ns(self, s: int) -> int:
        return self.base_ns + int(self.sc.stamps_ns[s])

    def messages(self, s: int) -> list[tuple[str, Any]]:
        """(topic, msg) of step ``s`` in arrival order: gyro, gps (if a fix), odometry.
        Steps are taken in order, each once."""
        if s != self._next:
            raise ValueError(f"step {s}: the devices are at step {self._next}")
        self._next += 1
        sc, i = self.sc, self.i
        st = self.stamp_ns(s)
        if s:
            p = motion(
                np.array([self._odo.x, self._odo.y, self._odo.theta]),
                (sc.dsr[i, s], sc.dsl[i, s]),
                sc.wheelbase_m,
            )
            self._odo = Pose2D(float(p[0]), float(p[1]), float(p[2]))
        dt = sc.dt
        vr, vl = sc.dsr[i, s] / dt, sc.dsl[i, s] / dt
        w = float((vr - vl) / sc.wheelbase_m)
        out: list[tuple[str, Any]] = [("gyro", GyroSample(st, w, float(sc.gyro[i, s])))]
        if not np.isnan(sc.gps[i, s, 0]):
            e, n = (float(v) for v in sc.gps[i, s])
            out.append(("gps", GpsFix(st, mode=3, quality=1, east_m=e, north_m=n)))
        odo = RobotOdometry(st, self._odo, float(vl), float(vr), float(0.5 * (vl + vr)), w, 12.5, True, True)  # fmt: skip
        out.append(("odometry", odo))
        return out

    def relative_scan(self, s: int, targets: Sequence[str]) -> RelativeScan | None:
        """The range-bearing sensor's scan of ``targets`` at step ``s`` (None if none)."""
        if not targets:
            return None
        sc, i, b = self.sc, self.i, self.sc.bounds
        st = self.stamp_ns(s)
        seen = []
        for t in targets:
            j = sc.names.index(t)
            r, brg = float(sc.rel_range[i, j, s]), float(sc.rel_bearing[i, j, s])
            seen.append(RelativeMeasurement(st, self.name, t, r, brg, b.range_m, b.bearing_rad))
        return RelativeScan(st, self.name, tuple(seen))

    def truth(self, s: int) -> Pose2D:
        t = self.sc.truth[self.i, s]
        return Pose2D(float(t[0]), float(t[1]), float(t[2]))


def _odometry_first(msgs: list[tuple[str, Any]]) -> list[tuple[str, Any]]:
    """The step's messages with the odometry first (a filter steps, then updates)."""
    return sorted(msgs, key=lambda tm: tm[0] != "odometry")


def _cp_bounds(cp: CPLocalizer) -> tuple[list[float], list[float]]:
    x, y, th = cp.current()
    return [float(x.lo), float(y.lo), float(th.lo)], [float(x.hi), float(y.hi), float(th.hi)]


class PaperRobot:
    """Robot ``index`` with the paper's three localizers in one process (the bench)."""

    def __init__(self, sc: Scenario, index: int, *, window: int = 40, outliers: int = 0) -> None:
        self.sc, self.i = sc, index
        self.name = sc.names[index]
        self.devices = PaperDevices(sc, index)
        b, g0 = sc.bounds, sc.gps[index, 0]
        init = PoseBox(
            0,
            self.name,
            Interval(g0[0] - b.gps_m, g0[0] + b.gps_m),
            Interval(g0[1] - b.gps_m, g0[1] + b.gps_m),
            Interval(sc.gyro[index, 0] - b.gyro_rad, sc.gyro[index, 0] + b.gyro_rad),
        )
        self.ekf = paper_ekf(sc, index)
        self.single = CPLocalizer(cp_config(sc, window, outliers), self.name, init)
        self.multi = CPLocalizer(cp_config(sc, window, outliers), self.name, init)
        self.monitor = IntegrityMonitor()
        self.tracks = {m: Track() for m in METHODS}
        self.truth: list[np.ndarray] = []

    def own_messages(self, s: int) -> list[tuple[str, object]]:
        """(topic, msg) of step ``s``: odometry, gyro, gps (if a fix)."""
        return _odometry_first(self.devices.messages(s))

    def relative_messages(self, s: int, targets: list[str]) -> list[RelativeMeasurement]:
        scan = self.devices.relative_scan(s, targets)
        return list(scan.seen) if scan is not None else []

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
        self.tracks["ekf"].record(*self.ekf.box_arrays(3.0), t)
        for name, cp in (("single_cp", self.single), ("multi_cp", self.multi)):
            self.tracks[name].record(*_cp_bounds(cp), t)
        self.monitor.check(self.ekf.estimate(), self.multi.box())


def summary(robots: list[PaperRobot], dt: float) -> dict[str, Any]:
    """The benchmark's figures over all robots (areas summed, containment pooled)."""
    results = []
    for r in robots:
        res: dict[str, Any] = {"steps": len(r.tracks["ekf"].area_m2)}
        for m in METHODS:
            res.update({f"{m}_{k}": v for k, v in r.tracks[m].figures(dt).items()})
        results.append(res)
    out = pooled(results)
    out["integrity_alarms"] = sum(len(r.monitor.alarms) for r in robots)
    out["gps_dropped"] = sum(len(r.multi.dropped_gps) for r in robots)
    return out


class PaperReference:
    """What ``hilnav fleet`` compares the runtime's cooperative CP with: the paper's EKF
    (3-sigma box) and the same CP service fed the robot's own sensors only."""

    methods = ("ekf", "single_cp")

    def __init__(self, sc: Scenario, index: int, cfg: RobotConfig, base_ns: int) -> None:
        self.ekf = paper_ekf(sc, index, base_ns)
        self.single = LocalizationAdapter(cfg)
        self.monitor = IntegrityMonitor()
        self.tracks = {m: Track() for m in self.methods}

    def feed(self, msgs: list[tuple[str, Any]]) -> None:
        for topic, m in msgs:
            self.single.feed(topic, m)
        for _, m in _odometry_first(msgs):
            self.ekf.feed(m)

    def record(self, truth: Sequence[float], multi: PoseBox) -> None:
        self.tracks["ekf"].record(*self.ekf.box_arrays(3.0), truth)
        b = self.single.cp.box()
        lo, hi = (b.x.lo, b.y.lo, b.theta.lo), (b.x.hi, b.y.hi, b.theta.hi)
        self.tracks["single_cp"].record(lo, hi, truth)
        self.monitor.check(self.ekf.estimate(), multi)

    def figures(self, dt: float) -> dict[str, Any]:
        out: dict[str, Any] = {"integrity_alarms": len(self.monitor.alarms)}
        for m in self.methods:
            out.update({f"{m}_{k}": v for k, v in self.tracks[m].figures(dt).items()})
        return out


@dataclass
class PaperScenario:
    """``hilnav fleet --scenario paper``: the paper's robots (more on further lanes)."""

    sc: Scenario
    window: int = 40

    @classmethod
    def build(cls, robots: int, duration_s: float, seed: int, window: int = 40) -> PaperScenario:
        return cls(simulate(paper_robots(robots), duration_s=duration_s, seed=seed), window)

    @property
    def names(self) -> list[str]:
        return list(self.sc.names)

    @property
    def dt_s(self) -> float:
        return self.sc.dt

    @property
    def steps(self) -> int:
        return self.sc.steps

    def config(self, robot: str, base: RobotConfig) -> RobotConfig:
        """``base`` with this robot's name, the fleet, its start (first GPS fix and gyro
        heading) and the CP service's bounds from the scenario's. No device drivers (the
        scenario is the devices); the CP service alone runs. The gyro's turn since its
        first sample may be off by two of its bounds; the start heading by one."""
        sc, i = self.sc, self.sc.names.index(robot)
        b, g0 = sc.bounds, sc.gps[i, 0]
        gyro_deg = math.degrees(b.gyro_rad)
        data = config_data(base)
        data.update(
            name=robot,
            fleet=sorted(set(self.names) | set(base.fleet)),
            initial_pose=[float(g0[0]), float(g0[1]), math.degrees(float(sc.gyro[i, 0]))],
        )
        for dev in data["devices"].values():
            dev["enabled"] = False
        data["geometry"]["wheel_base_m"] = sc.wheelbase_m
        sv = data["services"]
        for name in ("heading", "pose", "mapping"):
            sv[name]["enabled"] = False
        sv["localization"].update(
            enabled=True,
            publish_every_s=sc.dt,
            window=self.window,
            wheel_abs_bound_m=b.wheel_abs_m,
            wheel_rel_bound=b.wheel_rel,
            wheelbase_bound_m=0.0,
            gps_bound_m=b.gps_m,
            gps_outliers=0,
            gyro_bound_deg=2.0 * gyro_deg,
            gyro_drift_bound_degps=0.0,
            initial_bound_m=b.gps_m,
            initial_bound_deg=gyro_deg,
        )
        data["log"]["raw"] = False
        return parse_config(data, f"<fleet scenario paper: {robot}>")

    def devices(self, robot: str, base_ns: int) -> PaperDevices:
        return PaperDevices(self.sc, self.sc.names.index(robot), base_ns)

    def reference(self, robot: str, cfg: RobotConfig, base_ns: int) -> PaperReference:
        return PaperReference(self.sc, self.sc.names.index(robot), cfg, base_ns)
