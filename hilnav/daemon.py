"""The robot daemon: device threads, one service loop, the Zenoh bus and the MCAP log.

One reader thread per device (drivers from :mod:`hilnav.devices`) puts every decoded
message and the raw bytes of every read on ONE queue. One service loop takes them in
arrival order, feeds the :class:`hilnav.pipeline.Pipeline` (its mapping worker runs in its
own thread), and publishes and logs as :mod:`hilnav.topics` says; every
``diagnostics_period_s`` it emits a msgs.DeviceDiagnostics per device and a
msgs.DaemonStatus. ``cmd_vel`` from the fleet reaches the wheels through the
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
import queue
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hilnav.bus import Bus, ZenohSettings, zenoh_problem
from hilnav.config import RobotConfig
from hilnav.devices import make_drivers, with_fake_ports
from hilnav.fakeset import FakeProcess, FakeProcessError
from hilnav.log.encoding import stamp_of
from hilnav.motion import MotionGuard
from hilnav.peers import PeerTable
from hilnav.pipeline import Pipeline
from hilnav.sinks import Sink, Sinks, default_log_path, open_run_log
from hilnav.topics import DEVICE_TOPICS, PEER_TOPICS, PUBLISHED, log_topic, raw_topic
from msgs import DaemonStatus, DeviceDiagnostics, RawBytes, VelocityCommand


class DaemonError(RuntimeError):
    """The daemon cannot start (fakes, log directory, Zenoh): the message says why."""


@dataclass(slots=True)
class _Item:
    topic: str
    msg: Any
    recv_ns: int
    peer: str = ""  # set for another robot's message


@dataclass
class DaemonStats:
    """What the service loop did (read by the bench and the tests)."""

    processed: int = 0
    published: int = 0
    logged: int = 0  # taken by every sink (the log, the live view)
    dropped: int = 0
    by_topic: dict[str, int] = field(default_factory=dict)
    faults: dict[str, int] = field(default_factory=dict)


class Daemon:
    """One robot's daemon (see the module docstring). ``start()``, then ``stop()``."""

    # How long a thread holding the GIL keeps it while another waits (Python's default is
    # 5 ms): a reader or the service loop woken by a device read gets it from the mapping
    # thread's pure-Python steps after 0.5 ms. Set for the whole process by start().
    SWITCH_INTERVAL_S = 0.0005

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
        self.zenoh = zenoh or cfg.zenoh.settings()
        self.log_path = Path(log_path) if log_path else None
        self.stats = DaemonStats()
        self.errors: list[str] = []
        self._fault_kinds: set[tuple[str, str]] = set()
        self.pipeline = Pipeline(
            cfg, on_mapping=self._from_mapping, on_fault=self._fault, on_output=self._from_service
        )
        self.motion = MotionGuard(cfg.cmd_vel.limits(), self._on_motion_stop, self._fault)
        self.peers = PeerTable(cfg.services.localization.peer_timeout_s)
        # SimpleQueue: put and get in C, no Python-level condition per message; the bound
        # (messages dropped beyond it) is checked on its size
        self._q: queue.SimpleQueue[_Item] = queue.SimpleQueue()
        self._queue_size = queue_size
        self._pending: dict[str, list[tuple[str, Any]]] = {}  # per device: one read's items
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self.drivers: dict[str, Any] = {}
        self.bus: Bus | None = None
        self.log: Any = None
        self.sinks = Sinks(sinks or {}, self._fault)  # + "log" when the log opens
        self._log_topics: dict[str, str] = {}  # topic -> /<robot>/<topic>
        self.fake: FakeProcess | None = None
        self._loop_thread: threading.Thread | None = None
        self._stopped = False

    # -- lifecycle ------------------------------------------------------------------------------
    def start(self) -> None:
        sys.setswitchinterval(min(sys.getswitchinterval(), self.SWITCH_INTERVAL_S))
        try:
            self.bus = Bus(self.robot, self.zenoh, fleet=self.cfg.fleet)
        except Exception as exc:  # zenoh.ZError and friends
            raise DaemonError(f"cannot open the Zenoh session: {zenoh_problem(exc)}") from None
        try:
            if self.cfg.simulated:
                self._start_fakes()
            self._open_log()
            self._declare()
            self.drivers = make_drivers(self.cfg, self._raw_hook)
            self.motion.driver = self.drivers.get("arcos")
            for name, drv in self.drivers.items():
                self._thread(self._reader, f"dev-{name}", name, drv)
            self._loop_thread = self._thread(self._service_loop, "services")
            self.motion.start()
            self.bus.declare_alive()
        except BaseException:
            self.stop()
            raise

    def _thread(self, target: Any, name: str, *args: Any) -> threading.Thread:
        t = threading.Thread(target=target, args=args, name=name, daemon=True)
        t.start()
        self._threads.append(t)
        return t

    def _start_fakes(self) -> None:
        ep = self.zenoh.listen[0] if self.zenoh.listen else None
        if ep is not None:
            host_port = ep.split("/", 1)[1]
            if host_port.startswith(("0.0.0.0", "[::]")):
                ep = "tcp/127.0.0.1:" + host_port.rsplit(":", 1)[1]
        try:
            self.fake = FakeProcess(self.cfg, ep)
        except FakeProcessError as exc:
            raise DaemonError(str(exc)) from None
        self.cfg = with_fake_ports(self.cfg, self.fake.ports)

    def _declare(self) -> None:
        assert self.bus is not None
        self.bus.subscribe(self.robot, "cmd_vel", self._on_cmd_vel)
        self.bus.subscribe(self.robot, "truth", lambda r, m: self._put("truth", m))
        if self.cfg.services.localization.enabled:
            for topic in PEER_TOPICS:
                self.bus.subscribe("*", topic, lambda r, m, t=topic: self._on_peer(r, t, m))
            self.bus.on_liveliness(self._on_liveliness)
        latest = self.pipeline.latest
        for name in ("pose", "map", "info"):
            self.bus.queryable(name, lambda n=name: latest.get(n))

    def _open_log(self) -> None:
        if not self.cfg.log.enabled:
            return
        self.log_path = self.log_path or default_log_path(self.cfg)
        sim, services = self.fake is not None, self.pipeline.services
        try:
            self.log = open_run_log(self.cfg, self.log_path, simulated=sim, services=services)
        except OSError as exc:
            raise DaemonError(
                f"cannot write the log {self.log_path}: {exc.strerror or exc}; set [log] dir "
                "to a writable directory"
            ) from None
        self.sinks.add("log", self.log)

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
        self.motion.halt()
        for t in self._threads:
            t.join(timeout=5.0 if t is self._loop_thread else 3.0)
        self._drain()
        self.pipeline.close()
        for drv in self.drivers.values():
            with contextlib.suppress(Exception):
                drv.close()
        if self.bus is not None:
            with contextlib.suppress(Exception):
                self.bus.close()
        self.sinks.close()
        if self.fake is not None:
            self.fake.stop()

    def __enter__(self) -> Daemon:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- producers (device threads, Zenoh threads, the watchdog) ----------------------------------
    def _put(self, topic: str, msg: Any, peer: str = "") -> None:
        if self._q.qsize() >= self._queue_size:
            self.stats.dropped += 1
            return
        self._q.put(_Item(topic, msg, time.time_ns(), peer))

    def _put_read(self, pending: list[tuple[str, Any]]) -> None:
        """The items of one device read (its raw bytes, then its messages) as one queue
        entry, received at one time: one hand-over to the service loop per read."""
        if self._q.qsize() >= self._queue_size:
            self.stats.dropped += len(pending)
            return
        now = time.time_ns()
        self._q.put([_Item(topic, msg, now) for topic, msg in pending])

    def _raw_hook(self, device: str):
        if not self.cfg.log.raw or not self.cfg.log.enabled:
            return None
        topic = raw_topic(device)
        pending = self._pending.setdefault(device, [])  # sent by the device's reader

        def hook(data: bytes, stamp_ns: int) -> None:
            pending.append((topic, RawBytes(stamp_ns, device, bytes(data), "rx")))

        return hook

    def _reader(self, name: str, drv: Any) -> None:
        try:
            drv.open()
        except Exception as exc:
            drv.last_error = str(exc)
            self.errors.append(f"{name}: {exc}")
            print(f"hilnav run: {name}: {exc} (retrying)", file=sys.stderr, flush=True)
        pending = self._pending.setdefault(name, [])  # the raw hook's items, then ours
        while not self._stop.is_set():
            try:
                got = drv.read(0.2)
            except Exception as exc:
                drv.last_error = f"read failed: {exc!r}"
                time.sleep(0.2)
                got = []
            for m in got:
                topic = DEVICE_TOPICS.get(type(m))
                if topic is not None:
                    pending.append((topic, m))
            if pending:
                self._put_read(pending)
                pending.clear()

    def _on_cmd_vel(self, robot: str, cmd: VelocityCommand) -> None:
        if self._stop.is_set():
            return
        c = self.motion.command(cmd)
        if c is not None:
            self._put("cmd_vel", c)

    def _on_motion_stop(self, reason: str) -> None:
        if reason == "stall":
            self._fault("services", RuntimeError("service loop stalled: robot stopped"))
        self._put("cmd_vel", VelocityCommand(time.time_ns(), source=f"{self.robot}/{reason}"))

    def _on_peer(self, robot: str, topic: str, msg: Any) -> None:
        if robot != self.robot:
            self._put(topic, msg, peer=robot)

    def _on_liveliness(self, robot: str, alive: bool) -> None:
        if robot != self.robot:
            self._put("", alive, peer=robot)

    def _from_mapping(self, topic: str, msg: Any, recv_ns: Any) -> None:
        self._emit(topic, msg, int(recv_ns or time.time_ns()), publish=not self._stop.is_set())

    def _from_service(self, topic: str, msg: Any, recv_ns: Any) -> None:
        """A service's output, the moment it is made (the pose before CP runs)."""
        self._emit(topic, msg, int(recv_ns or time.time_ns()), publish=not self._stop.is_set())

    def _fault(self, where: str, exc: BaseException) -> None:
        """Count a fault, keep it for diagnostics, print its first occurrence per kind."""
        self.stats.faults[where] = self.stats.faults.get(where, 0) + 1
        text = f"{where}: {exc!r}"
        self.errors.append(text)
        del self.errors[:-100]
        kind = (where, type(exc).__name__)
        if kind not in self._fault_kinds:
            self._fault_kinds.add(kind)
            print(f"hilnav run: {text} (counted; the loop goes on)", file=sys.stderr, flush=True)

    # -- the service loop --------------------------------------------------------------------------
    def _service_loop(self) -> None:
        period = self.cfg.diagnostics_period_s
        next_diag = time.monotonic() + period
        while not self._stop.is_set():
            self.motion.heartbeat()
            try:
                item = self._q.get(timeout=0.05)
            except queue.Empty:
                item = None
            if type(item) is list:  # one device read
                for it in item:
                    self._handle_safely(it)
            elif item is not None:
                self._handle_safely(item)
            now = time.monotonic()
            for robot in self.peers.expire(now):
                self._guard("services", self.pipeline.drop_peer, robot)
            if now >= next_diag:
                next_diag = now + period
                self._guard("diagnostics", self._diagnostics)

    def _guard(self, where: str, fn: Any, *args: Any) -> None:
        try:
            fn(*args)
        except Exception as exc:
            self._fault(where, exc)

    def _handle_safely(self, item: _Item, publish: bool = True) -> None:
        self._guard("services", self._handle, item, publish)

    def _drain(self) -> None:
        while True:
            try:
                item = self._q.get_nowait()
            except queue.Empty:
                return
            for it in item if type(item) is list else [item]:
                self._handle_safely(it, publish=False)

    def _handle(self, item: _Item, publish: bool = True) -> None:
        topic, msg = item.topic, item.msg
        self.stats.processed += 1
        self.stats.by_topic[topic] = self.stats.by_topic.get(topic, 0) + 1
        if item.peer:
            self._handle_peer(item)
            return
        if topic == "info":
            self.pipeline.latest["info"] = msg
        self._emit(topic, msg, item.recv_ns, publish)
        self.pipeline.feed(topic, msg, item.recv_ns)  # outputs: self._from_service

    def _handle_peer(self, item: _Item) -> None:
        now = time.monotonic()
        if not item.topic:  # a liveliness change
            if self.peers.token(item.peer, bool(item.msg), now):
                self.pipeline.drop_peer(item.peer)
            return
        self.peers.seen(item.peer, now)
        self._log(log_topic(item.peer, item.topic), item.msg, item.recv_ns)
        for t, m in self.pipeline.feed_other(item.peer, item.topic, item.msg):
            self._emit(t, m, item.recv_ns)

    def _emit(self, topic: str, msg: Any, log_ns: int, publish: bool = True) -> None:
        """Publish (if ``topic`` is published) and log one message, encoded once: the bus
        sends the log's native record."""
        records = None
        if self.sinks:
            mcap_topic = self._log_topics.get(topic)
            if mcap_topic is None:
                mcap_topic = self._log_topics[topic] = log_topic(self.robot, topic)
            records = self.sinks.encode(mcap_topic, msg)
        if publish and topic in PUBLISHED and self.bus is not None:
            try:
                if records:
                    native = records[0]
                    self.bus.put_encoded(self.robot, topic, native.data, native.schema_name)
                else:
                    self.bus.publish(topic, msg)
                self.stats.published += 1
            except Exception as exc:
                self._fault("bus", exc)
        if records and self.sinks.write_records(records, log_ns, stamp_of(msg)):
            self.stats.logged += 1

    def _log(self, mcap_topic: str, msg: Any, log_ns: int) -> None:
        """To every sink (log, live view). Log time = when the daemon received the message
        (for a service output: when it received the input that caused it, as ``hilnav
        replay`` does); publish time = the message's own stamp (for device data the time
        its bytes were read)."""
        if self.sinks and self.sinks.write(mcap_topic, msg, log_ns):
            self.stats.logged += 1

    def _diagnostics(self) -> None:
        stamp = time.time_ns()
        for drv in self.drivers.values():
            try:
                d = drv.diagnostics(stamp)
            except Exception as exc:
                d = DeviceDiagnostics(stamp, getattr(drv, "device", "?"), last_error=repr(exc))
            self._emit("diagnostics", d, stamp)
        self._emit("status", self.status(stamp), stamp)

    def status(self, stamp_ns: int) -> DaemonStatus:
        """The daemon's own health counters (msgs.DaemonStatus)."""
        b = self.bus.stats if self.bus is not None else None
        g = self.motion.gate
        worker = self.pipeline.worker
        return DaemonStatus(
            stamp_ns,
            self.robot,
            bus_received=b.received if b else 0,
            bus_malformed=b.malformed if b else 0,
            bus_foreign=b.foreign if b else 0,
            bus_callback_errors=b.callback_errors if b else 0,
            bus_last_problem=b.last_problem if b else "",
            queue_processed=self.stats.processed,
            queue_dropped=self.stats.dropped + (worker.dropped if worker else 0),
            faults=dict(self.stats.faults),
            last_fault=self.errors[-1] if self.errors else "",
            cmd_received=g.received,
            cmd_rejected=g.rejected,
            cmd_timeouts=g.timeouts,
            cmd_stalls=g.stalls,
        )
