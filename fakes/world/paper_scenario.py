"""The multi-robot scenario of ekf-vs-cp.txt §2.4 with *bounded* sensor errors.

Three robots drive open-loop for 50 s at fixed wheel speeds (robot 1: right 0.98 m/s,
left 1.0 m/s; robot 2: straight at 1 m/s; robot 3: right 1.0, left 0.99 m/s). Each has
wheel encoders, a heading gyro and a GPS; for the cooperative case each also measures
range and bearing to the others. Every error is drawn uniformly inside a stated bound
(a little inside, so float rounding of the truth cannot step outside): that is the
set-membership assumption under which constraint propagation is guaranteed. The EKF is
given the matching standard deviations (bound / sqrt(3)). ``errors`` picks another error
model against the same bounds (fakes.world.error_models: gaussian, bias, heavy-tailed),
from the same random draws, so the truth and the seeds' world stay the same.

The truth moves on constant-curvature arcs per step. The world is deterministic for a
seed, so separate robot processes can each rebuild it and see the same truth (the fleet
uses this for the relative sensor); each robot's noise has its own seeded stream.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fakes.world.error_models import bias_signs, check_model, error
from msgs import Pose2D
from numerics.angles import wrap_angles


@dataclass(frozen=True)
class Bounds:
    """Guaranteed error bounds of the sensors (absolute values)."""

    wheel_abs_m: float = 0.0005
    wheel_rel: float = 0.01
    gps_m: float = 2.0
    gyro_rad: float = math.radians(1.0)
    range_m: float = 0.05
    bearing_rad: float = math.radians(1.0)


@dataclass(frozen=True)
class RobotSpec:
    name: str
    start: Pose2D
    right_mps: float
    left_mps: float


PAPER_ROBOTS: tuple[RobotSpec, ...] = (
    RobotSpec("r1", Pose2D(0.0, -5.0, 0.0), 0.98, 1.0),
    RobotSpec("r2", Pose2D(0.0, 0.0, 0.0), 1.0, 1.0),
    RobotSpec("r3", Pose2D(0.0, 5.0, 0.0), 1.0, 0.99),
)


def paper_robots(n: int = 3) -> tuple[RobotSpec, ...]:
    """The paper's three robots; more are added on further lanes (alternating turns)."""
    specs = list(PAPER_ROBOTS[: min(n, 3)])
    for i in range(3, n):
        lane = 5.0 * (i - 1) * (1 if i % 2 else -1)
        turn = 0.01 * (1 if i % 2 else -1)
        specs.append(RobotSpec(f"r{i + 1}", Pose2D(0.0, lane, 0.0), 1.0 + turn, 1.0))
    return tuple(specs)


@dataclass
class Scenario:
    """Truth and measurements of every robot; index [robot, step]."""

    names: list[str]
    dt: float
    wheelbase_m: float
    bounds: Bounds
    stamps_ns: np.ndarray  # (K+1,)
    truth: np.ndarray  # (N, K+1, 3), theta unwrapped
    dsr: np.ndarray  # (N, K+1) measured right wheel travel into step k (k >= 1)
    dsl: np.ndarray  # (N, K+1)
    gps: np.ndarray  # (N, K+1, 2), NaN where no fix
    gyro: np.ndarray  # (N, K+1) measured heading (unwrapped)
    rel_range: np.ndarray  # (N, N, K+1) observer i, target j
    rel_bearing: np.ndarray  # (N, N, K+1) in the observer's frame
    jumps: list[tuple[int, int]] = field(default_factory=list)  # (robot, step) outliers
    errors: str = "uniform"  # the error model (fakes.world.error_models)

    @property
    def steps(self) -> int:
        return self.stamps_ns.shape[0]


def _arc(p: np.ndarray, dr: float, dl: float, e: float) -> np.ndarray:
    d = 0.5 * (dr + dl)
    dth = (dr - dl) / e
    x, y, th = p
    if abs(dth) > 1e-12:
        r = d / dth
        return np.array(
            [
                x + r * (math.sin(th + dth) - math.sin(th)),
                y - r * (math.cos(th + dth) - math.cos(th)),
                th + dth,
            ]
        )
    return np.array([x + d * math.cos(th), y + d * math.sin(th), th])


def simulate(
    robots: tuple[RobotSpec, ...] = PAPER_ROBOTS,
    *,
    duration_s: float = 50.0,
    dt: float = 0.1,
    wheelbase_m: float = 0.33,
    bounds: Bounds | None = None,
    seed: int = 0,
    gps_every: int = 1,
    speed_jitter: float = 0.02,
    gps_jumps: tuple[tuple[int, int, float, float], ...] = (),
    errors: str = "uniform",
) -> Scenario:
    """Run the scenario. ``speed_jitter``: relative wheel-speed wobble of the truth
    (uniform, per step) so the motion is not perfectly regular; ``gps_jumps``: (robot,
    step, dx, dy) offsets added to single fixes (outliers beyond the bound); ``errors``:
    the error model of every sensor (fakes.world.error_models.ERROR_MODELS)."""
    model = check_model(errors)
    b = bounds or Bounds()
    n, k = len(robots), int(round(duration_s / dt))
    stamps = np.arange(k + 1, dtype=np.int64) * int(round(dt * 1e9))
    truth = np.zeros((n, k + 1, 3))
    dsr = np.zeros((n, k + 1))
    dsl = np.zeros((n, k + 1))
    gps = np.full((n, k + 1, 2), np.nan)
    gyro = np.zeros((n, k + 1))
    for i, spec in enumerate(robots):
        rng = np.random.default_rng([seed, i])
        sr, sl, sg, sx, sy = bias_signs(seed, i, 5)
        truth[i, 0] = (spec.start.x, spec.start.y, spec.start.theta)
        for s in range(1, k + 1):
            tr = spec.right_mps * dt * (1.0 + speed_jitter * rng.uniform(-1, 1))
            tl = spec.left_mps * dt * (1.0 + speed_jitter * rng.uniform(-1, 1))
            truth[i, s] = _arc(truth[i, s - 1], tr, tl, wheelbase_m)
            for true, out, sign in ((tr, dsr, sr), (tl, dsl, sl)):
                bound = b.wheel_abs_m + b.wheel_rel * abs(true)
                out[i, s] = true + error(model, bound, rng.uniform(-1, 1), sign)
        gyro[i] = truth[i, :, 2] + error(model, b.gyro_rad, rng.uniform(-1, 1, k + 1), sg)
        fix = np.arange(k + 1) % gps_every == 0
        err = error(model, b.gps_m, rng.uniform(-1, 1, (k + 1, 2)), np.array([sx, sy]))
        gps[i, fix] = truth[i, fix, :2] + err[fix]
    jumps = []
    for i, s, jx, jy in gps_jumps:
        gps[i, s] += (jx, jy)
        jumps.append((i, s))
    rel_r = np.zeros((n, n, k + 1))
    rel_b = np.zeros((n, n, k + 1))
    rng = np.random.default_rng([seed, 1000])
    signs = bias_signs(seed, 1000, 2 * n * n).reshape(n, n, 2)
    for i in range(n):
        for j in range(n):
            if i == j:
                continue
            d = truth[j, :, :2] - truth[i, :, :2]
            e_r = error(model, b.range_m, rng.uniform(-1, 1, k + 1), signs[i, j, 0])
            rel_r[i, j] = np.hypot(d[:, 0], d[:, 1]) + e_r
            brg = np.arctan2(d[:, 1], d[:, 0]) - truth[i, :, 2]
            brg = wrap_angles(brg)
            rel_b[i, j] = brg + error(
                model, b.bearing_rad, rng.uniform(-1, 1, k + 1), signs[i, j, 1]
            )
    return Scenario(
        names=[r.name for r in robots],
        dt=dt,
        wheelbase_m=wheelbase_m,
        bounds=b,
        stamps_ns=stamps,
        truth=truth,
        dsr=dsr,
        dsl=dsl,
        gps=gps,
        gyro=gyro,
        rel_range=rel_r,
        rel_bearing=rel_b,
        jumps=jumps,
        errors=model,
    )
