"""The robot daemon: one device loop, the services, the Zenoh bus and the MCAP log.

One device loop (:class:`hilnav.devloop.DeviceLoop`, one thread on epoll) reads every
device whose link is up (drivers from :mod:`hilnav.devices`; a thread per device only
while its link is down and being reopened) and takes the ONE queue that other threads
(Zenoh's callbacks, the watchdog) put their entries on. In that thread and in arrival
order, the :class:`hilnav.runtime.RobotRuntime` feeds the raw bytes of each read and its
decoded messages to the :class:`hilnav.pipeline.Pipeline` (its mapping worker runs in its
own thread), and publishes and logs as :mod:`hilnav.topics` says, each service output the moment it is
made and each message encoded once for bus and log; every ``diagnostics_period_s`` it
emits a msgs.DeviceDiagnostics per device and a msgs.DaemonStatus. ``cmd_vel`` from the fleet reaches the wheels through the
:class:`hilnav.motion.MotionGuard`, whose watchdog thread stops the robot on a command
timeout or a stalled loop. The fleet's pose boxes feed cooperative localization; peers
come and go by :class:`hilnav.peers.PeerTable`. Every message logged also goes to the other
sinks (:mod:`hilnav.sinks`: the live Foxglove view of ``hilnav run --foxglove``), encoded
once. An exception while handling one message is counted per place, reported on
``status`` and printed once per kind; the loop goes on.
Devices on "sim" ports are served by a ``hilnav fake`` child that dies with the daemon.
Stop: motors, readers, the queue drained into the log, drivers, Zenoh, log, fakes.
See docs/daemon.md.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from pathlib import Path
from typing import Any

from drivers.clock import now_ns
from hilnav.bus import Bus, ZenohSettings
from hilnav.config import RobotConfig
from hilnav.devices import DEVICES, make_drivers, with_fake_ports
from hilnav.devloop import DeviceLoop
from hilnav.fakeset import FakeProcess, FakeProcessError
from hilnav.motion import MotionGuard
from hilnav.osthread import NamedThread
from hilnav.peers import PeerTable
from hilnav.pipeline import Pipeline
from hilnav.runtime import RobotRuntime, RuntimeStats, StartError
from hilnav.sinks import Sink, Sinks
from hilnav.topics import DEVICE_TOPICS, PEER_TOPICS, raw_topic
from msgs import DaemonStatus, DeviceDiagnostics, RawBytes, VelocityCommand

DaemonError = StartError  # the daemon cannot start (fakes, log directory, Zenoh): says why
DaemonStats = RuntimeStats
# device messages the loop logs and publishes at once (the others in batches, at most
# every 0.1 s): odometry goes out before the pose made of it (the log's views need it)
PROMPT_TOPICS = frozenset({"odometry", "info"})
# devices the loop reads at each of its turns instead of being woken by them (those with
# no prompt topic: the gyro's 100 packets a second come in batches, before each SIP)
POLLED_DEVICES = frozenset(
    d.name for d in DEVICES.values() if not {DEVICE_TOPICS[m] for m in d.messages} & PROMPT_TOPICS
)
# queued by Zenoh's callbacks and the watchdog, taken at the loop's next turn (no wake-up
# of their own): logged only (truth, cmd_vel: the wheels got it in the callback), or
# used by cooperative localization at its next step (peers' boxes, liveliness: topic "")
LAZY_TOPICS = frozenset({"truth", "cmd_vel", "", *PEER_TOPICS})


class Daemon:
    """One robot's daemon (see the module docstring). ``start()``, then ``stop()``."""

    def __init__(
        self,
        cfg: RobotConfig,
        *,
        log_path: str | Path | None = None,
        zenoh: ZenohSettings | None = None,
        queue_size: int = 20000,
        sinks: dict[str, Sink] | None = None,
    ) -> None:
        self.cfg = cfg
        self.robot = cfg.name
        self.runtime = RobotRuntime(cfg, zenoh=zenoh, sinks=sinks, queue_size=queue_size)
        self.zenoh = self.runtime.zenoh
        self._log_path = Path(log_path) if log_path else None
        self.motion = MotionGuard(cfg.cmd_vel.limits(), self._on_motion_stop, self._fault)
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._pending: dict[str, list[tuple[str, Any]]] = {}  # per device: one read's items
        self.drivers: dict[str, Any] = {}
        self.fake: FakeProcess | None = None
        self._loop_thread: threading.Thread | None = None
        self._stopped = False
        period = self.cfg.diagnostics_period_s
        self._next_diag = time.monotonic() + period
        self.loop = DeviceLoop(
            self.runtime,
            read_device=self._read_device,
            prompt_topics=PROMPT_TOPICS,
            polled=POLLED_DEVICES,
            start_thread=lambda name, drv: self._thread(self._reader, f"dev-{name}", name, drv),
            heartbeat=self.motion.heartbeat,
            on_tick=self._tick,
            stop=self._stop,
            beat_s=min(0.1, cfg.cmd_vel.stall_s / 4),
        )
        self.runtime.wake = self.loop.wake  # what other threads queue wakes the loop ...
        self.runtime.lazy = LAZY_TOPICS  # ... but what it only logs, or uses at a step

    # the runtime's parts, as the daemon's
    @property
    def stats(self) -> RuntimeStats:
        return self.runtime.stats

    @property
    def errors(self) -> list[str]:
        return self.runtime.errors

    @property
    def pipeline(self) -> Pipeline:
        return self.runtime.pipeline

    @property
    def peers(self) -> PeerTable:
        return self.runtime.peers

    @property
    def bus(self) -> Bus | None:
        return self.runtime.bus

    @property
    def sinks(self) -> Sinks:
        return self.runtime.sinks

    @property
    def log(self) -> Any:
        return self.runtime.log

    @property
    def log_path(self) -> Path | None:
        return self.runtime.log_path or self._log_path

    # -- lifecycle ------------------------------------------------------------------------------
    def start(self) -> None:
        rt = self.runtime
        rt.open_bus()
        try:
            if self.cfg.simulated:
                self._start_fakes()
            rt.open_log(self._log_path, simulated=self.fake is not None)
            self._declare()
            self.drivers = make_drivers(self.cfg, self._raw_hook)
            self.motion.driver = self.drivers.get("arcos")
            for name, drv in self.drivers.items():
                self._pending.setdefault(name, [])
                self._thread(self._reader, f"dev-{name}", name, drv, True)
            self._loop_thread = self._thread(self.loop.run, "services")
            self.motion.start()
            assert rt.bus is not None
            rt.bus.declare_alive()
        except BaseException:
            self.stop()
            raise

    def _thread(self, target: Any, name: str, *args: Any) -> threading.Thread:
        t = NamedThread(target=target, args=args, name=name, daemon=True)
        t.start()
        self._threads.append(t)
        return t

    def _start_fakes(self) -> None:
        ep = _fake_endpoint(self.zenoh)
        try:
            self.fake = FakeProcess(self.cfg, ep)
        except FakeProcessError as exc:
            raise DaemonError(str(exc)) from None
        self.cfg = self.runtime.cfg = with_fake_ports(self.cfg, self.fake.ports)

    def _declare(self) -> None:
        bus = self.runtime.bus
        assert bus is not None
        bus.subscribe(self.robot, "cmd_vel", self._on_cmd_vel)
        bus.subscribe(self.robot, "truth", lambda r, m: self.runtime.put("truth", m))
        self.runtime.declare_peers()

    def wait(self, timeout_s: float | None = None) -> bool:
        """Block until :meth:`request_stop` (or the timeout); True if asked to stop."""
        return self._stop.wait(timeout_s)

    def request_stop(self) -> None:
        """Ask the daemon to stop (safe from a signal handler)."""
        self._stop.set()

    def stop(self) -> None:
        """Stop the motors, the readers and the loop; close log, bus, drivers, fakes."""
        if self._stopped:
            return
        self._stopped = True
        self._stop.set()
        self.loop.wake.set()
        self.runtime.closing.set()
        self.motion.halt()
        for t in list(self._threads):
            t.join(timeout=5.0 if t is self._loop_thread else 3.0)
        self.runtime.drain(publish=False)
        for drv in self.drivers.values():
            with contextlib.suppress(Exception):
                drv.close()
        self.runtime.close()
        self.loop.wake.close()  # after the bus: no producer is left to wake the loop
        if self.fake is not None:
            self.fake.stop()

    def __enter__(self) -> Daemon:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- producers (device threads, Zenoh threads, the watchdog) ----------------------------------
    def _put(self, topic: str, msg: Any) -> None:
        self.runtime.put(topic, msg)

    def _raw_hook(self, device: str):
        if not self.cfg.log.raw or not self.cfg.log.enabled:
            return None
        topic = raw_topic(device)
        pending = self._pending.setdefault(device, [])  # sent by the device's reader

        def hook(data: bytes, stamp_ns: int) -> None:
            pending.append((topic, RawBytes(stamp_ns, device, bytes(data), "rx")))

        return hook

    def _reader(self, name: str, drv: Any, opening: bool = False) -> None:
        """A device read by a thread of its own (no descriptor to wait on, or its link is
        down: the driver reconnects itself in ``read``), until the loop can take it."""
        if opening:
            try:
                drv.open()
            except Exception as exc:
                drv.last_error = str(exc)
                self.errors.append(f"{name}: {exc}")
                print(f"hilnav run: {name}: {exc} (retrying)", file=sys.stderr, flush=True)
        put_read = self.runtime.put_read
        fileno = getattr(drv, "fileno", _none)
        while not self._stop.is_set():
            if fileno() is not None:
                self.loop.adopt(name, drv)  # the link is up on a descriptor: the loop reads it
                return
            items = self._read_device(name, drv, 0.2)
            if items:
                put_read(items)

    def _read_device(self, name: str, drv: Any, timeout_s: float) -> list[tuple[str, Any]]:
        """One read of a device: the raw hook's items (its bytes), then its messages."""
        pending = self._pending[name]
        try:
            got = drv.read(timeout_s)
        except Exception as exc:
            drv.last_error = f"read failed: {exc!r}"
            if timeout_s > 0.0:
                time.sleep(0.2)
            got = ()
        for m in got:
            topic = DEVICE_TOPICS.get(type(m))
            if topic is not None:
                pending.append((topic, m))
        if not pending:
            return pending
        items = pending[:]
        pending.clear()
        return items

    def _on_cmd_vel(self, robot: str, cmd: VelocityCommand) -> None:
        if self._stop.is_set():
            return
        c = self.motion.command(cmd)
        if c is not None:
            self._put("cmd_vel", c)

    def _on_motion_stop(self, reason: str) -> None:
        if reason == "stall":
            self._fault("services", RuntimeError("service loop stalled: robot stopped"))
        self._put("cmd_vel", VelocityCommand(now_ns(), source=f"{self.robot}/{reason}"))

    def _fault(self, where: str, exc: BaseException) -> None:
        self.runtime.fault(where, exc)

    # -- the loop's periodic work -------------------------------------------------------------
    def _tick(self, now: float) -> None:
        rt = self.runtime
        rt.expire_peers(now)
        if now >= self._next_diag:
            self._next_diag = now + self.cfg.diagnostics_period_s
            rt.guard("diagnostics", self._diagnostics)

    def _diagnostics(self) -> None:
        stamp = now_ns()
        for drv in self.drivers.values():
            try:
                d = drv.diagnostics(stamp)
            except Exception as exc:
                d = DeviceDiagnostics(stamp, getattr(drv, "device", "?"), last_error=repr(exc))
            self.runtime.emit("diagnostics", d, stamp)
        self.runtime.emit("status", self.status(stamp), stamp)

    def status(self, stamp_ns: int) -> DaemonStatus:
        """The daemon's own health counters (msgs.DaemonStatus)."""
        g = self.motion.gate
        return self.runtime.status(
            stamp_ns,
            cmd_received=g.received,
            cmd_rejected=g.rejected,
            cmd_timeouts=g.timeouts,
            cmd_stalls=g.stalls,
        )


def _none() -> None:
    return None


def _fake_endpoint(z: ZenohSettings) -> str | None:
    """Where the ``hilnav fake`` child connects to publish the truth: the daemon's first
    listen endpoint (0.0.0.0 / [::] made loopback), or in client mode its first router."""
    if z.mode == "client":
        return z.connect[0] if z.connect else None
    ep = z.listen[0] if z.listen else None
    if ep is not None:
        host_port = ep.split("/", 1)[1]
        if host_port.startswith(("0.0.0.0", "[::]")):
            ep = "tcp/127.0.0.1:" + host_port.rsplit(":", 1)[1]
    return ep
