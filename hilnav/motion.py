"""The motion guard of a robot: bus commands to the wheels, and the watchdog that stops them.

:class:`MotionGuard` puts the pure :class:`hilnav.cmdvel.CmdVelGate` between the bus and
the Pioneer's driver and runs the gate's check on a timer thread of its own, outside the
service loop: a robot stops when no valid command came for ``cmd_vel.timeout_s`` after a
moving one, or when the service loop has not reported a heartbeat for ``cmd_vel.stall_s``
(while it is stalled, commands are refused). The watchdog sleeps until the gate's next
deadline (:meth:`hilnav.cmdvel.CmdVelGate.next_check`; a command that sets a stopped
robot moving wakes it), not on a fixed poll. Every stop is handed to ``on_stop`` so the
daemon can log it.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from typing import Any

from hilnav.cmdvel import CmdVelGate, CmdVelLimits
from hilnav.osthread import NamedThread
from msgs import VelocityCommand


class MotionGuard:
    SLACK_S = 0.002  # how long after a deadline the watchdog looks (the gate's > is strict)
    MAX_SLEEP_S = 1.0  # the longest it sleeps without looking

    def __init__(
        self,
        limits: CmdVelLimits,
        on_stop: Callable[[str], None],
        on_fault: Callable[[str, BaseException], None],
    ) -> None:
        self.gate = CmdVelGate(limits)
        self.driver: Any = None  # the Pioneer's driver (set once it exists)
        self._on_stop = on_stop
        self._on_fault = on_fault
        self._lock = threading.Lock()
        self._done = threading.Event()
        self._kick = threading.Event()  # a stopped robot was given a moving command
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        self._thread = NamedThread(target=self._watch, name="watchdog", daemon=True)
        self._thread.start()

    @property
    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def heartbeat(self) -> None:
        """The service loop came round."""
        with self._lock:
            self.gate.heartbeat(time.monotonic())

    def command(self, cmd: VelocityCommand) -> VelocityCommand | None:
        """Send a bus command to the wheels if the gate accepts it; the command sent."""
        with self._lock:
            if self._done.is_set():
                return None
            was_moving = self.gate.moving
            c = self.gate.accept(cmd, time.monotonic())
            if c is not None and self.driver is not None:
                self.driver.command(c)
            if self.gate.moving and not was_moving:
                self._kick.set()  # the watchdog sleeps until told: it has a deadline now
        return c

    def halt(self) -> None:
        """Stop the wheels for good (the daemon is stopping) and end the watchdog."""
        self._done.set()
        self._kick.set()
        with self._lock:
            self.gate.halt()
            if self.driver is not None:
                with contextlib.suppress(Exception):
                    self.driver.stop()
        if self._thread is not None:
            self._thread.join(1.0)

    def _watch(self) -> None:
        """Sleep until the gate's next deadline (or a command makes the robot move), then
        check: a stop comes ``SLACK_S`` after its deadline, with no polling between."""
        while not self._done.is_set():
            with self._lock:
                due = self.gate.next_check()
            wait = min(max(due - time.monotonic(), 0.0) + self.SLACK_S, self.MAX_SLEEP_S)
            if self._kick.wait(wait):
                self._kick.clear()
            if self._done.is_set():
                return
            try:
                self.check(time.monotonic())
            except Exception as exc:
                self._on_fault("watchdog", exc)

    def check(self, now: float) -> str | None:
        """Stop the wheels if the gate says so; the reason, or None."""
        with self._lock:
            reason = self.gate.check(now)
            if reason is not None and self.driver is not None:
                self.driver.stop()
        if reason is not None:
            self._on_stop(reason)
        return reason
