"""ARCOS client driver: handshake, keep-alive, commands, reconnect.

Connecting follows ARIA (ArRobot::asyncConnectHandler): SYNC0, SYNC1, SYNC2 in turn,
each retried until its echo arrives (1 s each); a SIP during sync means the robot is
still open from an earlier client, so CLOSE is sent and sync starts again. SYNC2's
reply names the robot, class and subclass (which pick the conversion factors). Then
OPEN, optionally CONFIG (answered with a 0x20 packet, waited for up to 1 s), ENABLE.

``read`` keeps the link alive (a PULSE when nothing was sent for ``pulse_s``, at most
0.5 s, well inside the robot's 2 s watchdog) and reconnects with exponential backoff
when the port disappears, the robot goes silent for ``silence_timeout_s`` or sends the
controller-reset packet 0xFF. ``send_*`` may be called from another thread.
A plain file of recorded bytes is decoded without handshake (replay).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from drivers.arcos.codec import ArcosCodec
from drivers.arcos.commands import Cmd, encode_command, vel2_argument
from drivers.arcos.packet import ArcosPacket
from drivers.arcos.packets import RESET_ID, SIP_MOVING, SIP_STOPPED, decode_sync2
from drivers.arcos.params import P3DX_SH, RobotParams, params_for
from drivers.base import Clock, DeviceError, LinkDiagnostics, RawHook, wall_clock_ns
from drivers.reconnect import Reconnect, ReconnectingLink, local_path
from drivers.transport import FileTransport, LinkLost, Transport, open_transport
from msgs import RobotInfo, RobotOdometry, VelocityCommand


@dataclass
class ArcosOptions:
    baud: int = 9600
    sync_timeout_s: float = 1.0
    sync_attempts: int = 5
    request_config: bool = True
    enable_motors: bool = True
    pulse_s: float = 0.4
    silence_timeout_s: float = 2.0
    reconnect_initial_s: float = 0.25
    reconnect_max_s: float = 1.0
    stream_encoders: bool = False


class ArcosDriver(LinkDiagnostics, ReconnectingLink):
    """One Pioneer over one link (see the module docstring)."""

    device = "arcos"

    def __init__(
        self,
        url: str,
        options: ArcosOptions | None = None,
        clock: Clock = wall_clock_ns,
        on_raw: RawHook | None = None,
    ) -> None:
        self.url = url
        self.opt = options or ArcosOptions()
        self.clock = clock
        self.on_raw = on_raw
        self.codec = ArcosCodec(P3DX_SH)
        self.info: RobotInfo | None = None
        self.connected = False
        self.reconnects = 0
        self.last_error = ""
        self.last_drop = ""
        self._t: Transport | None = None
        self._lock = threading.Lock()
        self._last_tx = 0.0
        self._last_rx = 0.0
        self._rc = Reconnect(
            self.opt.reconnect_initial_s, self.opt.reconnect_max_s, local_path(url)
        )
        self._pending: list[object] = []
        self._last_seen_ns = 0

    # -- connection -----------------------------------------------------------------
    def open(self) -> RobotInfo | None:
        """Connect and handshake; raises DeviceError (bad port, no answer)."""
        t = open_transport(self.url, self.opt.baud)
        try:
            if isinstance(t, FileTransport):
                self._t = t
                self.connected = True
                return None
            self._t = t
            self._handshake()
        except Exception:
            t.close()
            self._t = None
            raise
        self.connected = True
        self._last_rx = time.monotonic()
        self._rc.succeeded()
        self.last_error = ""
        return self.info

    def _raw_read(self, timeout_s: float) -> bytes:
        assert self._t is not None
        data = self._t.read(4096, timeout_s)
        if data and self.on_raw:
            self.on_raw(data, self.clock())
        return data

    def _write(self, data: bytes) -> None:
        with self._lock:
            if self._t is None:
                raise LinkLost(f"{self.url}: not connected")
            self._t.write(data)
            self._last_tx = time.monotonic()

    def _await(self, ids: tuple[int, ...], timeout_s: float) -> ArcosPacket | str | None:
        """Wait for a packet with one of ``ids``; 'open' if a SIP arrives instead."""
        deadline = time.monotonic() + timeout_s
        while (left := deadline - time.monotonic()) > 0:
            data = self._raw_read(min(left, 0.05))
            if not data:
                continue
            for msg in self.codec.feed(data, self.clock()):
                if isinstance(msg, ArcosPacket) and msg.packet_id in ids:
                    return msg
                if isinstance(msg, RobotOdometry) and SIP_STOPPED not in ids:
                    return "open"
                if isinstance(msg, RobotInfo) and 0x20 in ids:
                    self._config = msg
                    return ArcosPacket(0x20, b"", msg.stamp_ns)
        return None

    def _handshake(self) -> None:
        opt = self.opt
        for _attempt in range(opt.sync_attempts):
            step = 0
            name = ("", "", "")
            while step < 3:
                self._write(encode_command(step))
                got = self._await((step,), opt.sync_timeout_s)
                if got == "open":
                    # Still open from an earlier client: close it and start over.
                    self._write(encode_command(Cmd.CLOSE, 1))
                    time.sleep(0.2)
                    self._raw_read(0.05)
                    step = 0
                    break
                if got is None:
                    break
                assert isinstance(got, ArcosPacket)
                if step == 2:
                    name = decode_sync2(got.data)
                step += 1
            if step == 3:
                break
        else:
            raise DeviceError(
                f"{self.url}: no ARCOS robot answered the sync handshake after "
                f"{opt.sync_attempts} attempts; is the robot on, the baud rate right "
                f"({opt.baud}), and the cable in the robot's serial port?"
            )
        params = params_for(name[2])
        self.codec.params = params
        self.codec.odometry.reset_reference()
        self._write(encode_command(Cmd.OPEN, 1))
        self._config = None
        config: dict[str, int | str] = {}
        if opt.request_config:
            self._write(encode_command(Cmd.CONFIG, 1))
            got = self._await((0x20,), 1.0)
            if got is not None and self._config is not None:
                config = dict(self._config.config)
        self.info = RobotInfo(self.clock(), name[0], name[1], name[2], config)
        self._pending.append(self.info)
        if opt.enable_motors:
            self._write(encode_command(Cmd.ENABLE, 1))
        if opt.stream_encoders:
            self._write(encode_command(Cmd.ENCODER, 2))

    @property
    def params(self) -> RobotParams:
        return self.codec.params

    # -- the read loop ----------------------------------------------------------------
    def read(self, timeout_s: float) -> list[object]:
        """Messages decoded within ``timeout_s``; keeps alive and reconnects by itself."""
        out, self._pending = self._pending, []
        if not self.connected:
            self._try_reconnect()
            if not self.connected:
                time.sleep(self._rc.wait_s(time.monotonic(), timeout_s))
                return out
            out, self._pending = out + self._pending, []
        now = time.monotonic()
        if now - self._last_tx >= self.opt.pulse_s and not self._is_file:
            try:
                self._write(encode_command(Cmd.PULSE))
            except LinkLost as exc:
                self._drop_link(str(exc))
                return out
        try:
            data = self._raw_read(min(timeout_s, self.opt.pulse_s))
        except LinkLost as exc:
            self._drop_link(str(exc))
            return out
        now = time.monotonic()
        if not data:
            if self._is_file and self._t is not None and self._t.eof:
                return out
            if not self._is_file and now - self._last_rx > self.opt.silence_timeout_s:
                self._drop_link(f"{self.url}: robot silent for {self.opt.silence_timeout_s} s")
            return out
        self._last_rx = now
        for msg in self.codec.feed(data, self.clock()):
            if isinstance(msg, ArcosPacket):
                if msg.packet_id == RESET_ID:
                    self._drop_link(f"{self.url}: controller reset (packet 0xFF)")
                    self._rc.retry_at = 0.0
                continue
            if isinstance(msg, RobotOdometry):
                self._last_seen_ns = msg.stamp_ns
            out.append(msg)
        return out

    def fileno(self) -> int | None:
        """The port's descriptor while the link is up and has one (a device path), for a
        selector that calls ``read(0)`` when it is readable (and often enough for the
        keep-alive: at least every ``pulse_s`` / 2); else None."""
        t = self._t
        return t.fileno() if self.connected and t is not None else None

    @property
    def _is_file(self) -> bool:
        return isinstance(self._t, FileTransport)

    @property
    def eof(self) -> bool:
        return self._is_file and self._t is not None and self._t.eof

    # -- commands (thread-safe) ---------------------------------------------------------
    def send(self, data: bytes) -> bool:
        """Send raw command bytes; False if the link is down (the command is dropped)."""
        try:
            self._write(data)
            return True
        except LinkLost:
            return False

    def set_velocity(self, linear_mps: float, angular_radps: float) -> bool:
        """VEL (mm/s) + RVEL (deg/s), limited to the robot's top speeds."""
        p = self.params
        v = max(-p.max_trans_vel_mmps, min(p.max_trans_vel_mmps, linear_mps * 1000.0))
        w = max(-p.max_rot_vel_degps, min(p.max_rot_vel_degps, angular_radps * 57.29577951308232))
        return self.send(encode_command(Cmd.VEL, round(v)) + encode_command(Cmd.RVEL, round(w)))

    def set_wheels(self, left_mps: float, right_mps: float) -> bool:
        """VEL2: each wheel in units of Vel2Divisor (20 mm/s), -128..127."""
        arg = vel2_argument(left_mps * 1000.0, right_mps * 1000.0, self.params.vel2_divisor)
        return self.send(encode_command(Cmd.VEL2, arg))

    def command(self, cmd: VelocityCommand) -> bool:
        if cmd.left_mps is not None and cmd.right_mps is not None:
            return self.set_wheels(cmd.left_mps, cmd.right_mps)
        return self.set_velocity(cmd.linear_mps, cmd.angular_radps)

    def stop(self) -> bool:
        """ARIA's stop(): VEL 0 and RVEL 0 (decelerates), then STOP."""
        return self.set_velocity(0.0, 0.0) and self.send(encode_command(Cmd.STOP))

    def estop(self) -> bool:
        return self.send(encode_command(Cmd.ESTOP))

    def enable_motors(self, on: bool = True) -> bool:
        return self.send(encode_command(Cmd.ENABLE, 1 if on else 0))

    def reset_odometry(self) -> bool:
        """SETO: the robot zeroes its odometry; our reference restarts at the next SIP."""
        ok = self.send(encode_command(Cmd.SETO))
        self.codec.odometry.reset_reference()
        return ok

    def close(self) -> None:
        """Clean disconnect: ENABLE 0, CLOSE, then close the port."""
        if self._t is not None and self.connected and not self._is_file:
            self.send(encode_command(Cmd.ENABLE, 0) + encode_command(Cmd.CLOSE, 1))
            time.sleep(0.05)
        self.connected = False
        with self._lock:
            if self._t is not None:
                self._t.close()
                self._t = None


__all__ = ["ArcosDriver", "ArcosOptions", "SIP_MOVING"]
