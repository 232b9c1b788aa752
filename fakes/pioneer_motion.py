"""The emulated Pioneer's drive: motion commands, acceleration limits and odometry.

``DriveModel`` is the motion half of the ARCOS firmware. It holds what the motion
commands set (ENABLE, SETA, SETRA, SETV, SETRV, VEL, RVEL, VEL2, HEAD, DHEAD, MOVE,
STOP, ESTOP, SETO) and, stepped by the world, turns the targets into wheel speeds
within the acceleration limits. Its odometry is integrated as firmware does: from the
world robot's encoder ticks with the nominal wheel base (the truth, with slip, stays in
the world). Units are the firmware's: mm, mm/s, deg/s, and radians for headings.
"""

from __future__ import annotations

import math

from drivers.arcos.commands import Cmd, split_vel2
from drivers.arcos.params import RobotParams
from fakes.pioneer_config import PioneerConfig
from fakes.world.diffdrive import DiffDriveRobot
from msgs import wrap_angle


def approach(current: float, target: float, accel: float, decel: float, dt: float) -> float:
    """Move ``current`` towards ``target`` with accel when speeding up, decel when slowing."""
    speeding_up = abs(target) > abs(current) and current * target >= 0
    step = (accel if speeding_up else decel) * dt
    if abs(target - current) <= step:
        return target
    return current + math.copysign(step, target - current)


class DriveModel:
    """Motion targets, limits, current wheel speeds and odometry of one controller."""

    def __init__(self, cfg: PioneerConfig, params: RobotParams) -> None:
        self.cfg = cfg
        self.params = params
        # Firmware state kept across sessions: current speeds and odometry (mm, rad).
        self.cur_trans = 0.0  # mm/s
        self.cur_rot = 0.0  # deg/s
        self.cur_wheels = (0.0, 0.0)  # mm/s
        self.odo = [0.0, 0.0, 0.0]
        self.half_base_mm = 0.0
        self.ticks = (0, 0)  # the encoder counts at the last odometry step
        self.wheel_speed = (0.0, 0.0)  # mm/s the world's wheels were last commanded
        self.bumped = False
        self.reset_commands()

    def reset_commands(self) -> None:
        """What a new session starts from: motors off, no target, the default limits."""
        self.motors_enabled = False
        self.estopped = False
        self.mode = "vel"  # vel | wheels | head | move
        self.trans_target = 0.0  # mm/s
        self.rot_target = 0.0  # deg/s
        self.wheel_target = (0.0, 0.0)  # mm/s
        self.head_target = 0.0  # rad (firmware frame)
        self.move_left = 0.0  # mm left to travel in MOVE
        self.trans_accel = float(self.cfg.trans_accel_mmps2)
        self.trans_decel = float(self.cfg.trans_decel_mmps2)
        self.rot_accel = float(self.cfg.rot_accel_degps2)
        self.rot_decel = float(self.cfg.rot_decel_degps2)
        self.trans_max = float(self.cfg.trans_vel_max_mmps)
        self.rot_max = float(self.cfg.rot_vel_max_degps)
        self._paused: tuple | None = None

    def attach(self, robot: DiffDriveRobot) -> None:
        """Power up on ``robot``: at rest, odometry at zero, its encoder counts as the base."""
        self.cur_trans = 0.0
        self.cur_rot = 0.0
        self.cur_wheels = (0.0, 0.0)
        self.odo = [0.0, 0.0, 0.0]
        self.half_base_mm = robot.wheelbase_m * 500.0
        self.ticks = (robot.left_ticks, robot.right_ticks)
        self.wheel_speed = (0.0, 0.0)

    # -- the motion commands --------------------------------------------------------------
    def command(self, cid: int, n: int) -> bool:
        """Obey one motion command with int argument ``n``; False if ``cid`` is not one."""
        if cid == Cmd.ENABLE:
            self.motors_enabled = n != 0
            if n:
                self.estopped = False
        elif cid == Cmd.SETO:
            self.odo = [0.0, 0.0, 0.0]
        elif cid == Cmd.SETA:
            if n > 0:
                self.trans_accel = float(n)
            elif n < 0:
                self.trans_decel = float(-n)
        elif cid == Cmd.SETRA:
            if n > 0:
                self.rot_accel = float(n)
            elif n < 0:
                self.rot_decel = float(-n)
        elif cid == Cmd.SETV:
            self.trans_max = float(min(abs(n), self.cfg.trans_vel_max_mmps))
        elif cid == Cmd.SETRV:
            self.rot_max = float(min(abs(n), self.cfg.rot_vel_max_degps))
        elif cid == Cmd.VEL:
            self._to_vel_mode()
            self.trans_target = max(-self.trans_max, min(self.trans_max, float(n)))
        elif cid == Cmd.RVEL:
            self._to_vel_mode()
            self.rot_target = max(-self.rot_max, min(self.rot_max, float(n)))
        elif cid == Cmd.VEL2:
            self.mode = "wheels"
            self.wheel_target = tuple(float(v) for v in split_vel2(n, self.params.vel2_divisor))
        elif cid == Cmd.HEAD:
            self.mode = "head"
            self.head_target = math.radians(n)
        elif cid == Cmd.DHEAD:
            self.mode = "head"
            self.head_target = self.odo[2] + math.radians(n)
        elif cid == Cmd.MOVE:
            self.mode = "move"
            self.move_left = float(n)
            self.rot_target = 0.0
        elif cid in (Cmd.STOP, Cmd.ESTOP):
            self._halt(estop=cid == Cmd.ESTOP)
        else:
            return False
        return True

    def time_to_stop(self) -> float:
        """Seconds the wheels need to come to rest at the current deceleration limits."""
        lw, rw = self.cur_wheels
        t_trans = max(abs(self.cur_trans), abs(lw), abs(rw)) / max(self.trans_decel, 1e-9)
        return max(t_trans, abs(self.cur_rot) / max(self.rot_decel, 1e-9))

    def pause(self, within_s: float) -> None:
        """The watchdog: come to rest within ``within_s`` (decelerating harder than the
        limits if they would take longer), keeping the motion to resume later."""
        self._paused = (
            self.mode, self.trans_target, self.rot_target, self.wheel_target,
            self.head_target, self.move_left, self.trans_decel, self.rot_decel,
        )  # fmt: skip
        lw, rw = self.cur_wheels
        within_s = max(within_s, 1e-3)
        speed = max(abs(self.cur_trans), abs(lw), abs(rw))
        self.trans_decel = max(self.trans_decel, speed / within_s)
        self.rot_decel = max(self.rot_decel, abs(self.cur_rot) / within_s)
        self.mode = "wheels" if self.mode == "wheels" else "vel"
        self.trans_target = self.rot_target = 0.0
        self.wheel_target = (0.0, 0.0)

    def resume(self) -> None:
        """Communication is back: the motion the watchdog paused goes on (P3 manual)."""
        if self._paused is None:
            return
        (self.mode, self.trans_target, self.rot_target, self.wheel_target,
         self.head_target, self.move_left, self.trans_decel, self.rot_decel) = self._paused  # fmt: skip
        self._paused = None

    def halt(self) -> None:
        """At rest at once (the watchdog's last resort), the paused motion kept."""
        self.cur_trans = self.cur_rot = 0.0
        self.cur_wheels = (0.0, 0.0)

    def _halt(self, estop: bool) -> None:
        """STOP (or ESTOP, which also latches until ENABLE): at rest at once."""
        self.mode = "vel"
        if estop:
            self.estopped = True
        self.trans_target = self.rot_target = 0.0
        self.cur_trans = self.cur_rot = 0.0
        self.wheel_target = self.cur_wheels = (0.0, 0.0)

    def _to_vel_mode(self) -> None:
        if self.mode == "wheels":
            # Take over from the wheels' current motion without a jump.
            lw, rw = self.cur_wheels
            self.cur_trans = 0.5 * (lw + rw)
            self.cur_rot = math.degrees((rw - lw) / 2.0 / self.half_base_mm)
        if self.mode != "vel":
            self.trans_target = self.rot_target = 0.0
        self.mode = "vel"

    # -- the world side -------------------------------------------------------------------
    def step(self, dt: float) -> tuple[float, float]:
        """Wheel speeds (mm/s) for the next ``dt`` s: at rest unless enabled and not stopped."""
        if self.motors_enabled and not self.estopped:
            return self._motion(dt)
        self.cur_trans = self.cur_rot = 0.0
        self.cur_wheels = (0.0, 0.0)
        return 0.0, 0.0

    def _motion(self, dt: float) -> tuple[float, float]:
        half_base_mm = self.half_base_mm
        if self.mode == "wheels":
            lw, rw = self.cur_wheels
            tl, tr = self.wheel_target
            lw = approach(lw, tl, self.trans_accel, self.trans_decel, dt)
            rw = approach(rw, tr, self.trans_accel, self.trans_decel, dt)
            self.cur_wheels = (lw, rw)
            return lw, rw
        if self.mode == "head":
            err = wrap_angle(self.head_target - self.odo[2])
            self.rot_target = max(-self.rot_max, min(self.rot_max, math.degrees(2.0 * err)))
            if abs(err) < math.radians(0.5):
                self.rot_target = 0.0
        elif self.mode == "move":
            stop_dist = self.cur_trans**2 / (2.0 * self.trans_decel)
            if abs(self.move_left) <= max(stop_dist, 1.0):
                self.trans_target = 0.0
            else:
                self.trans_target = math.copysign(min(self.trans_max, 400.0), self.move_left)
            self.move_left -= self.cur_trans * dt
        self.cur_trans = approach(
            self.cur_trans, self.trans_target, self.trans_accel, self.trans_decel, dt
        )
        self.cur_rot = approach(self.cur_rot, self.rot_target, self.rot_accel, self.rot_decel, dt)
        w = math.radians(self.cur_rot)
        diff = w * half_base_mm
        self.cur_wheels = (self.cur_trans - diff, self.cur_trans + diff)
        return self.cur_wheels

    def integrate_odometry(self, robot: DiffDriveRobot) -> None:
        """Advance the odometry by the encoder ticks since the last call (nominal base)."""
        lt, rt = robot.left_ticks, robot.right_ticks
        pl, pr = self.ticks
        self.ticks = (lt, rt)
        k = 1000.0 / robot.ticks_per_m
        dl, dr = (lt - pl) * k, (rt - pr) * k
        d = 0.5 * (dl + dr)
        dth = (dr - dl) / (robot.wheelbase_m * 1000.0)
        th = self.odo[2]
        self.odo[0] += d * math.cos(th + 0.5 * dth)
        self.odo[1] += d * math.sin(th + 0.5 * dth)
        self.odo[2] = wrap_angle(th + dth)
        self.wheel_speed = (robot.left_cmd_mps * 1000.0, robot.right_cmd_mps * 1000.0)
        self.bumped = robot.bumped
