"""The emulated Pioneer's session layer: handshake, OPEN, CLOSE, watchdog, command dispatch.

``ArcosSession`` takes the command packets the port received, in order:

- before OPEN, SYNC0/SYNC1 are answered with bare echoes and SYNC2 with name, class and
  subclass; OPEN (with or without its argument: the manual's "OPEN 1 none") after a
  complete handshake starts a session (``_handshake``);
- the watchdog (``check_watchdog``, called every SIP cycle) has the wheels at rest
  ``watchdog_ms`` after the last packet (deceleration included); the next packet resumes
  the motion, as the Pioneer 3 manual says;
- in a session, CLOSE forgets it, CONFIG is answered, ENCODER 2 turns the ENCODER stream
  on, and the motion commands go to the drive (``fakes.pioneer_motion.DriveModel``);
  anything else is counted as unknown.

Replies go out through the ``send`` callable given (the emulator's fault-injecting
writer). The caller holds the emulator's lock around every method.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from drivers.arcos.commands import Cmd, decode_argument
from drivers.arcos.packets import CONFIG_ID, encode_config, encode_sync2
from fakes.pioneer_config import PioneerConfig
from fakes.pioneer_motion import DriveModel
from fakes.pioneer_packets import config_values

# Commands ARIA sends that the emulated robot accepts and ignores (no sonar, no I/O).
IGNORED_COMMANDS = (Cmd.SONAR, Cmd.BUMPSTALL, Cmd.IOREQUEST, Cmd.HOSTBAUD, Cmd.BATTERYINFO)


class ArcosSession:
    """Session state of one controller and the counters tests read across sessions."""

    def __init__(
        self, cfg: PioneerConfig, drive: DriveModel, send: Callable[[int, bytes], None]
    ) -> None:
        self.cfg = cfg
        self.drive = drive
        self._send = send
        self.reset()
        self.unknown_commands = 0
        self.watchdog_trips = 0
        self.sessions = 0

    def reset(self) -> None:
        """Forget the session (CLOSE, a controller reset, the port vanishing)."""
        self.sync_state = 0  # 0..3; 3 = synced, waiting for OPEN
        self.opened = False
        self.stream_encoders = False
        self.last_rx = time.monotonic()
        self.watchdog_tripped = False
        self.drive.reset_commands()

    def receive(self, cid: int, data: bytes) -> None:
        """One command packet (ID ``cid``, argument bytes ``data``) from the host."""
        self.last_rx = time.monotonic()
        if self.watchdog_tripped:
            self.watchdog_tripped = False
            if self.opened:  # CLOSE resumes nothing: it resets the session below
                self.drive.resume()
        try:
            arg = decode_argument(data)
        except ValueError:
            self.unknown_commands += 1
            return
        if not self.opened:
            self._handshake(cid, arg)
            return
        self._command(cid, arg)

    # -- handshake, OPEN and the watchdog -------------------------------------------------
    def _handshake(self, cid: int, arg: int | bytes | None) -> None:
        """SYNC0, SYNC1, SYNC2 (each answered), then OPEN starts the session."""
        if cid == Cmd.OPEN and self.sync_state == 3:  # "OPEN 1 none": also without argument
            self.opened = True
            self.sessions += 1
            return
        if cid in (0, 1, 2) and arg is None:
            if cid == 0:
                self.sync_state = 1
                self._send(0, b"")
            elif cid == 1 and self.sync_state >= 1:
                self.sync_state = 2
                self._send(1, b"")
            elif cid == 2 and self.sync_state >= 2:
                self.sync_state = 3
                self._send(2, encode_sync2(self.cfg.name, self.cfg.robot_class, self.cfg.subclass))
            return

    def check_watchdog(self, now: float) -> None:
        """The wheels are at rest ``watchdog_ms`` after the last packet: the stop begins a
        ramp (at most half the timeout, harder than the limits if need be) before it, and
        anything still moving at the timeout stops at once. The motion resumes with the
        next packet."""
        limit = self.cfg.watchdog_ms / 1000.0
        if not self.opened or limit <= 0:
            return
        silent = now - self.last_rx
        ramp = min(self.drive.time_to_stop(), limit / 2.0) + self.cfg.sip_cycle_ms / 1000.0
        if not self.watchdog_tripped and silent >= limit - ramp:
            self.watchdog_tripped = True
            self.watchdog_trips += 1
            self.drive.pause(max(limit - silent - self.cfg.sip_cycle_ms / 1000.0, 0.0))
        if self.watchdog_tripped and silent >= limit - self.cfg.sip_cycle_ms / 1000.0:
            self.drive.halt()

    # -- commands in a session ------------------------------------------------------------
    def _command(self, cid: int, arg: int | bytes | None) -> None:
        n = arg if isinstance(arg, int) else 0
        if cid == Cmd.PULSE:
            return
        if cid == Cmd.CLOSE:
            self.reset()
        elif cid == Cmd.CONFIG:
            self._send(CONFIG_ID, encode_config(config_values(self.cfg, self.drive)))
        elif cid == Cmd.ENCODER:
            self.stream_encoders = n == 2
        elif cid in IGNORED_COMMANDS:
            pass
        elif not self.drive.command(cid, n):
            self.unknown_commands += 1
