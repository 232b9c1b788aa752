"""Simulated Pioneer runs for the fusion benches: messages as the drivers report them, truth.

One run: the robot stands still 3 s (as after boot), then drives a random route of
straight segments and turns on a flat floor until it has rolled ``length_m``. The truth
is the fakes' own ground-truth robot (fakes.world.DiffDriveRobot with its SlipModel:
per-wheel radius error, white slip growing with the distance rolled, wheel-base error),
stepped at 100 Hz directly, without ptys or a World (no walls on a flat floor). From it:

- RobotOdometry at 10 Hz, integrated from the quantised encoder ticks with the nominal
  wheel base, exactly as the emulated ARCOS firmware (fakes/pioneer_motion.py) does, and
  quantised like a SIP (1 mm positions, 2 pi / 4096 headings);
- GyroSample at 100 Hz from the fakes' CruzCore error model (fakes.world.GyroErrorModel:
  turn-on bias, bias random walk, white noise, scale error), the angle integrated by the
  device and both quantised to the packet's 0.01 deg(/s) LSB;
- GpsFix at 1 Hz from the fakes' GPS error model (fakes.world.GpsErrorModel: white noise
  plus a Gauss-Markov bias) in local metres, with the GST sigma the fake receiver claims.

Nothing here is tuned for the filters: the error models are the fakes' defaults.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fakes.world import DiffDriveRobot, GpsErrorModel, GyroErrorModel, SlipModel
from msgs import GpsFix, GyroSample, Pose2D, RobotOdometry, wrap_angle

DEG = math.pi / 180.0
ANGLE_UNIT = 2.0 * math.pi / 4096.0
GYRO_LSB = 0.01 * DEG


@dataclass
class SimRun:
    """Messages in arrival order; truth and distance at every odometry message."""

    seed: int
    length_m: float
    messages: list[object] = field(default_factory=list)
    odo_stamps: list[int] = field(default_factory=list)
    truth: list[Pose2D] = field(default_factory=list)
    distance_m: list[float] = field(default_factory=list)
    gyro_scale: float = 1.0
    gyro_bias_degps: float = 0.0


def route(rng: np.random.Generator, length_m: float) -> list[tuple[float, float]]:
    """Waypoints from (0, 0): straight legs of 1.5-8 m joined by turns of 20-160 deg."""
    pts = [(0.0, 0.0)]
    heading, total = 0.0, 0.0
    first = True
    while total < length_m + 2.0:
        if not first:
            heading += rng.choice([-1.0, 1.0]) * rng.uniform(20.0, 160.0) * DEG
        first = False
        leg = rng.uniform(1.5, 8.0)
        x, y = pts[-1]
        pts.append((x + leg * math.cos(heading), y + leg * math.sin(heading)))
        total += leg
    return pts[1:]


class FirmwareOdometry:
    """Odometry as the ARCOS firmware keeps it: encoder ticks, nominal wheel base (m, rad)."""

    def __init__(self, robot: DiffDriveRobot) -> None:
        self.base = robot.wheelbase_m
        self.k = 1.0 / robot.ticks_per_m
        self.ticks = (robot.left_ticks, robot.right_ticks)
        self.odo = [0.0, 0.0, 0.0]

    def update(self, robot: DiffDriveRobot) -> Pose2D:
        """Integrate the ticks since the last call; the pose quantised as a SIP reports it."""
        odo = self.odo
        lt, rt = robot.left_ticks, robot.right_ticks
        dl, dr = (lt - self.ticks[0]) * self.k, (rt - self.ticks[1]) * self.k
        self.ticks = (lt, rt)
        d, dth = 0.5 * (dl + dr), (dr - dl) / self.base
        odo[0] += d * math.cos(odo[2] + 0.5 * dth)
        odo[1] += d * math.sin(odo[2] + 0.5 * dth)
        odo[2] = wrap_angle(odo[2] + dth)
        return Pose2D(
            round(odo[0] * 1000.0) / 1000.0,
            round(odo[1] * 1000.0) / 1000.0,
            wrap_angle(round(odo[2] / ANGLE_UNIT) * ANGLE_UNIT),
        )


def steer_to(
    robot: DiffDriveRobot, target: tuple[float, float], speed_mps: float, max_turn_radps: float
) -> bool:
    """Command the wheels towards ``target``; True once it is within 0.15 m."""
    tx, ty = target
    p = robot.pose
    dx, dy = tx - p.x, ty - p.y
    reached = math.hypot(dx, dy) < 0.15
    err = wrap_angle(math.atan2(dy, dx) - p.theta)
    w = max(-max_turn_radps, min(max_turn_radps, 2.0 * err))
    v = 0.0 if abs(err) > 20 * DEG else speed_mps * max(0.3, math.cos(err))
    base = robot.wheelbase_m
    robot.command_wheels(v - 0.5 * w * base, v + 0.5 * w * base)
    return reached


def gyro_sample(stamp: int, rate: float, angle: float) -> GyroSample:
    """The CruzCore packet: rate and integrated angle quantised to its 0.01 deg(/s) LSB."""
    return GyroSample(
        stamp,
        round(rate / GYRO_LSB) * GYRO_LSB,
        round(angle / GYRO_LSB) * GYRO_LSB,
        wrap_angle(round(angle / GYRO_LSB) * GYRO_LSB),
    )


def odometry_message(stamp: int, robot: DiffDriveRobot, pose: Pose2D) -> RobotOdometry:
    """What the ARCOS driver reports for a SIP with ``pose``: wheel speeds, flags, battery."""
    moving = abs(robot.left_cmd_mps) > 5e-4 or abs(robot.right_cmd_mps) > 5e-4
    return RobotOdometry(
        stamp,
        pose,
        robot.left_cmd_mps,
        robot.right_cmd_mps,
        robot.speed_mps,
        robot.yaw_rate_radps,
        12.5,
        moving,
        True,
    )  # fmt: skip


def gps_fix(stamp: int, truth: Pose2D, err: np.ndarray, gps: GpsErrorModel) -> GpsFix:
    """A 3D fix at the true position plus the model's error, with the sigma GST claims."""
    sigma = gps.horizontal_sigma_m
    return GpsFix(
        stamp,
        mode=3,
        quality=1,
        satellites=9,
        hdop=gps.hdop,
        std_lat_m=sigma,
        std_lon_m=sigma,
        east_m=truth.x + float(err[0]),
        north_m=truth.y + float(err[1]),
    )  # fmt: skip


def simulate(
    seed: int,
    length_m: float,
    dt: float = 0.01,
    odo_every: int = 10,
    gps_every: int = 100,
    speed_mps: float = 0.4,
    max_turn_radps: float = 0.6,
    rest_s: float = 3.0,
    slip: SlipModel | None = None,
    gyro: GyroErrorModel | None = None,
    gps: GpsErrorModel | None = None,
    with_gps: bool = True,
) -> SimRun:
    """One run (see the module docstring): rest, then the seed's route until ``length_m``."""
    rng = np.random.default_rng(seed)
    robot = DiffDriveRobot("r1", slip=slip or SlipModel(), seed=seed + 1)
    gyro = gyro or GyroErrorModel(seed=seed + 2)
    gps = gps or GpsErrorModel(seed=seed + 3)
    run = SimRun(seed, length_m, gyro_scale=gyro.scale, gyro_bias_degps=gyro.bias_radps / DEG)
    wps = route(rng, length_m)
    wp = 0
    firmware = FirmwareOdometry(robot)
    g_angle = 0.0
    n_rest = int(round(rest_s / dt))
    stamp = 0
    step = 0
    dt_ns = int(round(dt * 1e9))
    max_steps = n_rest + int(6.0 * length_m / speed_mps / dt) + 2000
    while step < max_steps:
        step += 1
        stamp += dt_ns
        if step <= n_rest or wp >= len(wps):
            robot.command_wheels(0.0, 0.0)
        elif steer_to(robot, wps[wp], speed_mps, max_turn_radps):
            wp += 1
        robot.step(dt)
        rate = gyro.sample(robot.yaw_rate_radps, dt)
        g_angle += rate * dt
        run.messages.append(gyro_sample(stamp, rate, g_angle))
        if step % odo_every == 0:
            run.messages.append(odometry_message(stamp, robot, firmware.update(robot)))
            run.odo_stamps.append(stamp)
            run.truth.append(robot.pose)
            run.distance_m.append(robot.distance_m)
            if robot.distance_m >= length_m:
                break
        if with_gps and step % gps_every == 0:
            err = gps.sample(gps_every * dt)
            if err is not None:
                run.messages.append(gps_fix(stamp, robot.pose, err, gps))
    return run


def run_lengths(n: int = 20, lo: float = 5.0, hi: float = 60.0) -> list[float]:
    """n route lengths spread evenly over [lo, hi] metres (the paper's 5-60 m)."""
    return [lo + (hi - lo) * i / (n - 1) for i in range(n)] if n > 1 else [hi]
