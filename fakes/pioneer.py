"""An emulated Pioneer 3-DX: ARCOS firmware on a virtual serial port, moved by the world.

Behaves like the ARCOS controller as ARIA and MobileSim (EmulatePioneer) expect:
- answers SYNC0/SYNC1 with bare echoes and SYNC2 with name, class and subclass;
  skips junk such as ARIA's ``WMS2\\r``;
- after OPEN streams a standard SIP every SipCycleTime (100 ms), 0x33 while moving;
  answers CONFIG with a 0x20 packet, streams ENCODER packets after ENCODER 2;
- ENABLE, SETA, SETV, SETRV, SETRA, VEL, RVEL, VEL2, HEAD, DHEAD, MOVE, STOP, ESTOP, SETO
  with acceleration limits; the watchdog (2 s) stops the motors when nothing arrives
  and ARCOS resumes on the next command; CLOSE ends the session;
- odometry as firmware does: integrated from the world robot's encoder ticks with the
  nominal wheel base (the truth, with slip, stays in the world).
Fault knobs: corrupt a fraction of the bytes sent, drop whole packets, vanish (the port
goes away) and reappear, pace output at the baud rate; controller_reset() (the 0xFF
packet, session forgotten) and go_silent()/recover() (a hung controller) for tests.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass

import numpy as np

from drivers.arcos.commands import Cmd, decode_argument, split_vel2
from drivers.arcos.packet import PacketParser, frame
from drivers.arcos.packets import (
    CONFIG_ID,
    ENCODER_ID,
    RESET_ID,
    SIP_MOVING,
    SIP_STOPPED,
    encode_config,
    encode_encoder,
    encode_sip,
    encode_sync2,
)
from drivers.arcos.params import P3DX_SH, RobotParams
from fakes.pty import VirtualSerialPort
from msgs import wrap_angle


@dataclass
class PioneerFaults:
    """Fault injection: probabilities per byte / per packet; vanish schedule in seconds."""

    corrupt_byte_prob: float = 0.0
    drop_packet_prob: float = 0.0
    vanish_after_s: float | None = None
    vanish_for_s: float = 2.0


@dataclass
class PioneerConfig:
    name: str = "hilnav-fake"
    robot_class: str = "Pioneer"
    subclass: str = "p3dx-sh"
    sip_cycle_ms: int = 100
    watchdog_ms: int = 2000
    trans_accel_mmps2: int = 300
    trans_decel_mmps2: int = 300
    rot_accel_degps2: int = 100
    rot_decel_degps2: int = 100
    trans_vel_max_mmps: int = 1500
    rot_vel_max_degps: int = 360
    battery_v: float = 12.8
    baud: int | None = None
    serial_number: str = "FAKE0001"
    firmware: str = "hilnav-arcos-emu 1.0"


def _approach(current: float, target: float, accel: float, decel: float, dt: float) -> float:
    """Move ``current`` towards ``target`` with accel when speeding up, decel when slowing."""
    speeding_up = abs(target) > abs(current) and current * target >= 0
    step = (accel if speeding_up else decel) * dt
    if abs(target - current) <= step:
        return target
    return current + math.copysign(step, target - current)


class PioneerEmulator:
    """ARCOS firmware for one world robot (see the module docstring)."""

    def __init__(
        self,
        robot: str,
        config: PioneerConfig | None = None,
        faults: PioneerFaults | None = None,
        params: RobotParams = P3DX_SH,
        seed: int = 0,
        device_name: str = "arcos",
    ) -> None:
        self.name = device_name
        self.robot_name = robot
        self.cfg = config or PioneerConfig()
        self.faults = faults or PioneerFaults()
        self.params = params
        self._rng = np.random.default_rng(seed)
        self._lock = threading.Lock()
        self.port: VirtualSerialPort | None = None
        self._runner = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._reset_session()
        self.unknown_commands = 0
        self.watchdog_trips = 0
        self.sessions = 0
        self.hung = False

    def _reset_session(self) -> None:
        self.sync_state = 0  # 0..3; 3 = synced, waiting for OPEN
        self.opened = False
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
        self.stream_encoders = False
        self.last_rx = time.monotonic()
        self.watchdog_tripped = False

    # -- lifecycle --------------------------------------------------------------------
    def start(self, runner) -> None:  # noqa: ANN001 (FakeRunner; avoids an import cycle)
        self._runner = runner
        robot = runner.world.robots[self.robot_name]
        # Firmware state: current wheel speeds (mm/s) and odometry (mm, rad).
        self.cur_trans = 0.0
        self.cur_rot = 0.0
        self.cur_wheels = (0.0, 0.0)
        self.odo = [0.0, 0.0, 0.0]
        self._half_base_mm = robot.wheelbase_m * 500.0
        self._ticks = (robot.left_ticks, robot.right_ticks)
        self._wheel_speed = (0.0, 0.0)
        self.port = VirtualSerialPort(runner.link_dir / self.name, baud=self.cfg.baud)
        self._t0 = time.monotonic()
        self._thread = threading.Thread(target=self._serve, name=f"fake-{self.name}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        if self.port is not None:
            self.port.close()

    def ports(self) -> dict[str, str]:
        return {self.name: self.port.path} if self.port else {}

    def vanish(self) -> None:
        if self.port:
            self.port.vanish()
        with self._lock:
            self._reset_session()

    def reappear(self) -> None:
        if self.port:
            self.port.reappear()

    def controller_reset(self) -> None:
        """The microcontroller resets: it sends the 0xFF packet and forgets the session."""
        with self._lock:
            self._reset_session()
        self._send(RESET_ID)

    def go_silent(self) -> None:
        """The firmware hangs: the port stays, but nothing more is sent or answered."""
        with self._lock:
            self._reset_session()
            self.hung = True

    def recover(self) -> None:
        """The hung firmware comes back (like a power cycle): it answers a new handshake."""
        self.hung = False

    # -- the serial side ------------------------------------------------------------------
    def _send(self, packet_id: int, data: bytes = b"") -> None:
        if self.port is None:
            return
        if self.faults.drop_packet_prob and self._rng.random() < self.faults.drop_packet_prob:
            return
        raw = bytearray(frame(packet_id, data))
        p = self.faults.corrupt_byte_prob
        if p:
            hit = self._rng.random(len(raw)) < p
            for i in np.flatnonzero(hit):
                raw[i] ^= int(self._rng.integers(1, 256))
        self.port.write(bytes(raw))

    def _serve(self) -> None:
        parser = PacketParser(inter_byte_timeout_ns=0)
        next_sip = time.monotonic()
        vanished_at: float | None = None
        while not self._stop.is_set():
            now = time.monotonic()
            f = self.faults
            if (
                f.vanish_after_s is not None
                and vanished_at is None
                and now - self._t0 >= f.vanish_after_s
            ):
                self.vanish()
                vanished_at = now
            if vanished_at is not None and now - vanished_at >= f.vanish_for_s:
                self.reappear()
                vanished_at = None
                f.vanish_after_s = None
            data = self.port.read(max(0.0, min(0.02, next_sip - now)))
            if data and not self.hung:
                for pkt in parser.feed(data, time.monotonic_ns()):
                    with self._lock:
                        self._handle(pkt.packet_id, pkt.data)
            now = time.monotonic()
            if now >= next_sip:
                next_sip += self.cfg.sip_cycle_ms / 1000.0
                if next_sip < now:
                    next_sip = now + self.cfg.sip_cycle_ms / 1000.0
                with self._lock:
                    self._check_watchdog(now)
                    if self.opened and not self.hung:
                        sip_id, sip = self._sip()
                        enc = self._ticks if self.stream_encoders else None
                    else:
                        sip = None
                if sip is not None:
                    self._send(sip_id, sip)
                    if enc is not None:
                        self._send(ENCODER_ID, encode_encoder(*enc))

    def _check_watchdog(self, now: float) -> None:
        if not self.opened or self.cfg.watchdog_ms <= 0:
            return
        if now - self.last_rx > self.cfg.watchdog_ms / 1000.0 and not self.watchdog_tripped:
            self.watchdog_tripped = True
            self.watchdog_trips += 1
            self.mode = "vel"
            self.trans_target = self.rot_target = 0.0
            self.wheel_target = (0.0, 0.0)

    def _handle(self, cid: int, data: bytes) -> None:
        self.last_rx = time.monotonic()
        self.watchdog_tripped = False
        try:
            arg = decode_argument(data)
        except ValueError:
            self.unknown_commands += 1
            return
        if not self.opened:
            if cid in (0, 1, 2) and arg is None:
                if cid == 0:
                    self.sync_state = 1
                    self._send(0)
                elif cid == 1 and self.sync_state >= 1:
                    self.sync_state = 2
                    self._send(1)
                elif cid == 2 and self.sync_state >= 2:
                    self.sync_state = 3
                    self._send(
                        2, encode_sync2(self.cfg.name, self.cfg.robot_class, self.cfg.subclass)
                    )
                return
            if cid == Cmd.OPEN and self.sync_state == 3:
                self.opened = True
                self.sessions += 1
            return
        self._command(cid, arg)

    def _command(self, cid: int, arg: int | bytes | None) -> None:
        n = arg if isinstance(arg, int) else 0
        if cid == Cmd.PULSE:
            return
        if cid == Cmd.CLOSE:
            self._reset_session()
        elif cid == Cmd.ENABLE:
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
        elif cid == Cmd.STOP:
            self.mode = "vel"
            self.trans_target = self.rot_target = 0.0
            self.cur_trans = self.cur_rot = 0.0
            self.wheel_target = self.cur_wheels = (0.0, 0.0)
        elif cid == Cmd.ESTOP:
            self.mode = "vel"
            self.estopped = True
            self.trans_target = self.rot_target = 0.0
            self.cur_trans = self.cur_rot = 0.0
            self.wheel_target = self.cur_wheels = (0.0, 0.0)
        elif cid == Cmd.CONFIG:
            self._send(CONFIG_ID, encode_config(self._config_values()))
        elif cid == Cmd.ENCODER:
            self.stream_encoders = n == 2
        elif cid in (Cmd.SONAR, Cmd.BUMPSTALL, Cmd.IOREQUEST, Cmd.HOSTBAUD, Cmd.BATTERYINFO):
            pass
        else:
            self.unknown_commands += 1

    def _to_vel_mode(self) -> None:
        if self.mode == "wheels":
            # Take over from the wheels' current motion without a jump.
            lw, rw = self.cur_wheels
            self.cur_trans = 0.5 * (lw + rw)
            self.cur_rot = math.degrees((rw - lw) / 2.0 / self._half_base_mm)
        if self.mode != "vel":
            self.trans_target = self.rot_target = 0.0
        self.mode = "vel"

    def _config_values(self) -> dict[str, int | str]:
        c = self.cfg
        return {
            "Type": c.robot_class,
            "SubType": c.subclass,
            "SerialNumber": c.serial_number,
            "RotVelTop": c.rot_vel_max_degps,
            "TransVelTop": c.trans_vel_max_mmps,
            "RotAccelTop": 300,
            "TransAccelTop": 1000,
            "PwmMax": 1000,
            "Name": c.name,
            "SipCycleTime": c.sip_cycle_ms,
            "HostBaud": 0,
            "FrontSonar": 0,
            "LowBattery": 115,
            "RevCount": 16570,
            "Watchdog": c.watchdog_ms,
            "RotVelMax": int(self.rot_max),
            "TransVelMax": int(self.trans_max),
            "RotAccel": int(self.rot_accel),
            "RotDecel": int(self.rot_decel),
            "TransAccel": int(self.trans_accel),
            "TransDecel": int(self.trans_decel),
            "FrontBumps": 5,
            "RearBumps": 5,
            "ResetBaud": 0,
            "TicksMM": 128,
            "ShutdownVoltage": 105,
            "FirmwareVersion": c.firmware,
        }

    # -- the world side (called by the runner with the world locked) ---------------------
    def tick(self, dt: float) -> None:
        if self._runner is None:
            return
        robot = self._runner.world.robots[self.robot_name]
        with self._lock:
            self._integrate_odometry(robot)
            left, right = (
                self._motion(dt) if self.motors_enabled and not self.estopped else (0.0, 0.0)
            )
            if not (self.motors_enabled and not self.estopped):
                self.cur_trans = self.cur_rot = 0.0
                self.cur_wheels = (0.0, 0.0)
        robot.command_wheels(left / 1000.0, right / 1000.0)

    def _motion(self, dt: float) -> tuple[float, float]:
        half_base_mm = self._half_base_mm
        if self.mode == "wheels":
            lw, rw = self.cur_wheels
            tl, tr = self.wheel_target
            lw = _approach(lw, tl, self.trans_accel, self.trans_decel, dt)
            rw = _approach(rw, tr, self.trans_accel, self.trans_decel, dt)
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
        self.cur_trans = _approach(
            self.cur_trans, self.trans_target, self.trans_accel, self.trans_decel, dt
        )
        self.cur_rot = _approach(self.cur_rot, self.rot_target, self.rot_accel, self.rot_decel, dt)
        w = math.radians(self.cur_rot)
        diff = w * half_base_mm
        self.cur_wheels = (self.cur_trans - diff, self.cur_trans + diff)
        return self.cur_wheels

    def _integrate_odometry(self, robot) -> None:  # noqa: ANN001
        lt, rt = robot.left_ticks, robot.right_ticks
        pl, pr = self._ticks
        self._ticks = (lt, rt)
        k = 1000.0 / robot.ticks_per_m
        dl, dr = (lt - pl) * k, (rt - pr) * k
        d = 0.5 * (dl + dr)
        dth = (dr - dl) / (robot.wheelbase_m * 1000.0)
        th = self.odo[2]
        self.odo[0] += d * math.cos(th + 0.5 * dth)
        self.odo[1] += d * math.sin(th + 0.5 * dth)
        self.odo[2] = wrap_angle(th + dth)
        self._wheel_speed = (robot.left_cmd_mps * 1000.0, robot.right_cmd_mps * 1000.0)
        self._bumped = robot.bumped

    def _sip(self) -> tuple[int, bytes]:
        p = self.params
        lv, rv = self._wheel_speed
        moving = abs(lv) > 0.5 or abs(rv) > 0.5
        th_units = int(round(self.odo[2] / p.angle_conv))
        th_units = ((th_units + 2048) % 4096) - 2048
        bumped = getattr(self, "_bumped", False)
        stall = (0x1 | 0x100) if bumped and moving else 0
        if bumped and self.cur_trans > 0:
            stall |= 0x2 << 8  # a front bumper
        elif bumped and self.cur_trans < 0:
            stall |= 0x2  # a rear bumper
        flags = (0x1 if self.motors_enabled else 0) | (0x20 if self.estopped else 0)
        batt = self.cfg.battery_v
        rotvel = math.degrees((rv - lv) / 2.0 / self._half_base_mm) * 10.0
        fields = {
            "XPOS": int(round(self.odo[0] / p.dist_conv)) & 0x7FFF,
            "YPOS": int(round(self.odo[1] / p.dist_conv)) & 0x7FFF,
            "THPOS": th_units,
            "L_VEL": int(round(lv / p.vel_conv)),
            "R_VEL": int(round(rv / p.vel_conv)),
            "BATTERY": int(round(batt * 10)) & 0xFF,
            "STALL_AND_BUMPERS": stall,
            "CONTROL": int(round(math.degrees(self.head_target) / 360 * 4096))
            if self.mode == "head"
            else 0,
            "FLAGS": flags,
            "COMPASS": 0,
            "GRIP_STATE": 0,
            "ANPORT": 0,
            "ANALOG": 0,
            "DIGIN": 0,
            "DIGOUT": 0,
            "BATTERYX10": int(round(batt * 10)),
            "CHARGESTATE": 0,
            "ROTVEL": int(round(rotvel)),
            "FAULTFLAGS": 0,
        }
        return (SIP_MOVING if moving else SIP_STOPPED), encode_sip(fields)
