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

This module holds the emulator itself: its port, its serving thread (the SIP clock and
the vanish schedule), the fault injection on what it sends, and the world tick. The
firmware's parts live beside it: ``fakes.pioneer_session`` (handshake, OPEN, CLOSE, the
watchdog, command dispatch), ``fakes.pioneer_motion`` (motion commands, acceleration
limits, odometry), ``fakes.pioneer_packets`` (SIP and CONFIG contents) and
``fakes.pioneer_config`` (the firmware settings).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import numpy as np

from drivers.arcos.packet import PacketParser, frame
from drivers.arcos.packets import ENCODER_ID, RESET_ID, encode_encoder
from drivers.arcos.params import P3DX_SH, RobotParams
from fakes.pioneer_config import PioneerConfig
from fakes.pioneer_motion import DriveModel
from fakes.pioneer_packets import sip_packet
from fakes.pioneer_session import ArcosSession
from fakes.streaming import PortEmulator


@dataclass
class PioneerFaults:
    """Fault injection: probabilities per byte / per packet; vanish schedule in seconds."""

    corrupt_byte_prob: float = 0.0
    drop_packet_prob: float = 0.0
    vanish_after_s: float | None = None
    vanish_for_s: float = 2.0


class PioneerEmulator(PortEmulator):
    """ARCOS firmware for one world robot (see the module docstring).

    ``session`` is the session layer (``opened``, ``sessions``, ``watchdog_trips``,
    ``unknown_commands``), ``drive`` the motion model and odometry.
    """

    def __init__(
        self,
        robot: str,
        config: PioneerConfig | None = None,
        faults: PioneerFaults | None = None,
        params: RobotParams = P3DX_SH,
        seed: int = 0,
        device_name: str = "arcos",
    ) -> None:
        super().__init__(device_name)
        self.robot_name = robot
        self.cfg = config or PioneerConfig()
        self.faults = faults or PioneerFaults()
        self.params = params
        self._rng = np.random.default_rng(seed)
        self._lock = threading.Lock()
        self._runner = None
        self.drive = DriveModel(self.cfg, params)
        self.session = ArcosSession(self.cfg, self.drive, self._send)
        self.hung = False

    # -- lifecycle --------------------------------------------------------------------
    def start(self, runner) -> None:
        self._runner = runner
        self.drive.attach(runner.world.robots[self.robot_name])
        self._t0 = time.monotonic()
        self._open(runner, baud=self.cfg.baud)

    def vanish(self) -> None:
        if self.port:
            self.port.vanish()
        with self._lock:
            self.session.reset()

    def reappear(self) -> None:
        if self.port:
            self.port.reappear()

    def controller_reset(self) -> None:
        """The microcontroller resets: it sends the 0xFF packet and forgets the session."""
        with self._lock:
            self.session.reset()
        self._send(RESET_ID)

    def go_silent(self) -> None:
        """The firmware hangs: the port stays, but nothing more is sent or answered."""
        with self._lock:
            self.session.reset()
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
            vanished_at = self._vanish_on_schedule(now, vanished_at)
            data = self.port.read(max(0.0, min(0.02, next_sip - now)))
            if data and not self.hung:
                for pkt in parser.feed(data, time.monotonic_ns()):
                    with self._lock:
                        self.session.receive(pkt.packet_id, pkt.data)
            now = time.monotonic()
            if now >= next_sip:
                next_sip += self.cfg.sip_cycle_ms / 1000.0
                if next_sip < now:
                    next_sip = now + self.cfg.sip_cycle_ms / 1000.0
                for packet_id, payload in self._sip_cycle(now):
                    self._send(packet_id, payload)

    def _vanish_on_schedule(self, now: float, vanished_at: float | None) -> float | None:
        """Vanish and reappear as the faults say; returns when the port vanished (or None)."""
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
        return vanished_at

    def _sip_cycle(self, now: float) -> list[tuple[int, bytes]]:
        """The watchdog's check, then this cycle's SIP (and ENCODER) packets, if in a session."""
        with self._lock:
            self.session.check_watchdog(now)
            if not self.session.opened or self.hung:
                return []
            packets = [sip_packet(self.drive, self.params, self.cfg.battery_v)]
            if self.session.stream_encoders:
                packets.append((ENCODER_ID, encode_encoder(*self.drive.ticks)))
        return packets

    # -- the world side (called by the runner with the world locked) ---------------------
    def tick(self, dt: float) -> None:
        if self._runner is None:
            return
        robot = self._runner.world.robots[self.robot_name]
        with self._lock:
            self.drive.integrate_odometry(robot)
            left, right = self.drive.step(dt)
        robot.command_wheels(left / 1000.0, right / 1000.0)
