"""The robot daemon: device threads, one service loop, the Zenoh bus and the MCAP log.

As in DESIGN.md "Data flow on a robot": one reader thread per device calls its driver's
``read`` (blocking, with a timeout; drivers reconnect by themselves) and puts every
decoded message, and the raw bytes of every read (msgs.RawBytes), on ONE queue. One
service loop takes them in arrival order, feeds the :class:`hilnav.pipeline.Pipeline`,
publishes device messages and service outputs on ``hilnav/<robot>/<topic>``, and logs
every message to one MCAP file per run (``/<robot>/<topic>``, raw bytes on
``/<robot>/raw/<device>``). Every ``diagnostics_period_s`` it publishes and logs one
msgs.DeviceDiagnostics per device (plus ``bus``: samples received / malformed / foreign,
and ``queue``: messages dropped because the loop fell behind).

Bus: liveliness token ``hilnav/<robot>/alive``; queryables ``query/pose`` (latest pose),
``query/map`` (latest map) and ``query/info``; subscription to ``hilnav/<robot>/cmd_vel``
(only from fleet members) forwarded to the Pioneer through :class:`hilnav.cmdvel.CmdVelGate`
(finite, clamped to ``[cmd_vel]`` limits). A motion watchdog thread, outside the service
loop, stops the robot when no command arrives for ``cmd_vel.timeout_s`` after a moving one,
or when the service loop has not come round for ``cmd_vel.stall_s``.

Fault containment: no single input stops a loop. Inbound samples are validated when
decoded (msgs.decode); an exception while handling one message (services, log, bus) is
counted per place in ``DaemonStats.faults``, reported on the ``queue`` diagnostics, printed
once per kind, and the loop goes on with the next message.
Poses of other fleet robots (``pose_box``) go to the pipeline for cooperative
localization.

Simulation: devices whose port is ``sim`` are served by ``hilnav fake`` started as a
subprocess (office plan by default, IR board on CAN behind its emulated slcan adapter);
the fake process publishes the world's ground truth on ``hilnav/<robot>/truth`` and the
daemon logs it as topic ``truth`` (it is not fed to the services).

Shutdown (:meth:`Daemon.stop`, on SIGINT/SIGTERM in ``hilnav run``): stop the motors,
stop the readers, drain the queue into the log, close the drivers (motors disabled),
undeclare everything from Zenoh, close the log, stop the fakes.
"""

from __future__ import annotations

import contextlib
import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgs
from hilnav.bus import Bus, ZenohSettings
from hilnav.cmdvel import CmdVelGate
from hilnav.config import RobotConfig, ir_board_config
from hilnav.pipeline import Pipeline
from msgs import (
    DeviceDiagnostics,
    GpsFix,
    GyroSample,
    IrScan,
    RawBytes,
    RobotInfo,
    RobotOdometry,
    VelocityCommand,
)

DEVICE_TOPICS: dict[type, str] = {
    RobotOdometry: "odometry",
    GyroSample: "gyro",
    GpsFix: "gps",
    IrScan: "ir",
    RobotInfo: "info",
}
# Topics the daemon publishes on Zenoh (raw bytes and truth are only logged).
PUBLISHED = {
    "odometry",
    "gyro",
    "gps",
    "ir",
    "info",
    "heading",
    "pose",
    "pose_box",
    "map",
    "association",
    "diagnostics",
}


class DaemonError(RuntimeError):
    """The daemon cannot start (fakes, log directory, Zenoh): the message says why."""


@dataclass
class _Item:
    topic: str
    msg: Any
    recv_ns: int


@dataclass
class DaemonStats:
    """What the service loop did (read by the bench and the tests)."""

    processed: int = 0
    published: int = 0
    logged: int = 0
    dropped: int = 0
    cmd_received: int = 0
    cmd_rejected: int = 0
    cmd_timeouts: int = 0
    cmd_stalls: int = 0
    by_topic: dict[str, int] = field(default_factory=dict)
    faults: dict[str, int] = field(default_factory=dict)


def open_log_writer(path: Path, compression: str, metadata: dict[str, str]) -> Any:
    """The LOG helper's LogWriter (hilnav.log.writer)."""
    try:
        from hilnav.log.writer import LogWriter
    except ImportError:  # pragma: no cover - until hilnav.log is merged
        return _MinimalLog(path, compression, metadata)
    return LogWriter(path, compression=compression, metadata=metadata)


class _MinimalLog:
    """Stand-in MCAP writer (native hilnav JSON channels only) while hilnav.log is absent."""

    def __init__(self, path: Path, compression: str, metadata: dict[str, str]) -> None:
        from mcap.writer import CompressionType, Writer

        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4}.get(
            compression, CompressionType.NONE
        )
        self._f = open(path, "wb")  # noqa: SIM115 - closed in close()
        self._w = Writer(self._f, compression=comp)
        self._w.start(profile="", library="hilnav")
        self._w.add_metadata("hilnav", metadata)
        self._ch: dict[str, int] = {}
        self._sch: dict[str, int] = {}
        self._lock = threading.Lock()
        self._last_flush = time.monotonic()
        self.messages_written = 0

    def write(self, topic: str, msg: Any, log_time_ns: int, publish_time_ns: int | None = None):
        cls = type(msg)
        name = msgs.schema_name(cls)
        with self._lock:
            cid = self._ch.get(topic)
            if cid is None:
                sid = self._sch.get(name)
                if sid is None:
                    sid = self._w.register_schema(
                        name, "jsonschema", json.dumps(msgs.json_schema(cls)).encode()
                    )
                    self._sch[name] = sid
                cid = self._w.register_channel(topic, "json", sid)
                self._ch[topic] = cid
            self._w.add_message(cid, log_time_ns, msgs.encode(msg), publish_time_ns or log_time_ns)
            self.messages_written += 1
            if time.monotonic() - self._last_flush >= 1.0:
                self._w.flush()
                self._last_flush = time.monotonic()

    def close(self) -> None:
        with self._lock:
            if self._f.closed:
                return
            self._w.finish()
            self._f.close()


# -- drivers ------------------------------------------------------------------------------
def make_drivers(cfg: RobotConfig, on_raw) -> dict[str, Any]:  # noqa: ANN001
    """One driver per enabled device; ``on_raw(device)`` gives each its raw-bytes hook."""
    from drivers.arcos.driver import ArcosDriver, ArcosOptions
    from drivers.cruzcore_driver import CruzCoreDriver
    from drivers.irboard.driver import IrCanDriver, IrSerialDriver
    from drivers.nmea.driver import NmeaDriver
    from drivers.nmea.local import Datum

    d = cfg.devices
    out: dict[str, Any] = {}
    if d.arcos.enabled:
        out["arcos"] = ArcosDriver(
            d.arcos.port, ArcosOptions(baud=d.arcos.baud), on_raw=on_raw("arcos")
        )
    if d.ir.enabled:
        ir = d.ir
        board = ir_board_config(cfg)
        if ir.link == "can":
            out["ir"] = IrCanDriver(
                ir.can_interface,
                ir.can_channel or ir.port,
                board,
                bitrate=ir.can_bitrate,
                on_raw=on_raw("ir"),
            )
        else:
            out["ir"] = IrSerialDriver(ir.port, board, baud=ir.baud, on_raw=on_raw("ir"))
    if d.gyro.enabled:
        out["gyro"] = CruzCoreDriver(
            d.gyro.port, baud=d.gyro.baud, rate_hz=d.gyro.rate_hz, on_raw=on_raw("gyro")
        )
    if d.gps.enabled:
        out["gps"] = NmeaDriver(
            d.gps.port, baud=d.gps.baud, datum=Datum(*d.gps.datum), on_raw=on_raw("gps")
        )
    return out


# -- simulation -------------------------------------------------------------------------------
class FakeProcess:
    """``hilnav fake`` in a subprocess for the devices whose port is "sim"."""

    def __init__(self, cfg: RobotConfig, zenoh_endpoint: str | None) -> None:
        d, sim = cfg.devices, cfg.simulation
        devices = [
            n
            for n in ("arcos", "ir", "gyro", "gps")
            if getattr(d, n).enabled and getattr(d, n).port == "sim"
        ]
        cmd = [
            sys.executable,
            "-m",
            "hilnav",
            "fake",
            "--plan",
            sim.plan,
            "--seed",
            str(sim.seed),
            "--robot",
            cfg.name,
            "--devices",
            ",".join(devices),
            "--ir-link",
            "slcan" if d.ir.link == "can" else "serial",
            "--ir-rate",
            str(d.ir.rate_hz),
            "--gyro-rate",
            str(d.gyro.rate_hz),
            "--gps-rate",
            str(sim.gps_rate_hz),
            "--corrupt",
            str(sim.corrupt),
        ]
        if zenoh_endpoint:
            cmd += ["--zenoh-connect", zenoh_endpoint, "--truth-rate", str(sim.truth_rate_hz)]
        env = dict(os.environ)
        root = str(Path(__file__).resolve().parents[1])
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH", "")) if p)
        self.proc = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
        )
        self.ports = self._read_ports(timeout_s=30.0)

    def _read_ports(self, timeout_s: float) -> dict[str, str]:
        got: list[str] = []
        t = threading.Thread(target=lambda: got.append(self.proc.stdout.readline()), daemon=True)
        t.start()
        t.join(timeout_s)
        line = got[0] if got else ""
        try:
            ports = json.loads(line)
        except ValueError:
            self.stop()
            err = self.proc.stderr.read() if self.proc.stderr else ""
            raise DaemonError(f"the emulated devices did not start: {err.strip()[-400:]}") from None
        return {str(k): str(v) for k, v in ports.items()}

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=5.0)
        for s in (self.proc.stdout, self.proc.stderr):
            if s is not None:
                s.close()


# -- the daemon ------------------------------------------------------------------------------------
class Daemon:
    """One robot's daemon (see the module docstring). ``start()``, then ``stop()``."""

    def __init__(
        self,
        cfg: RobotConfig,
        *,
        log_path: str | Path | None = None,
        zenoh: ZenohSettings | None = None,
        queue_size: int = 20000,
    ) -> None:
        self.cfg = cfg
        self.robot = cfg.name
        self.zenoh = zenoh or cfg.zenoh.settings()
        self.log_path = Path(log_path) if log_path else None
        self.stats = DaemonStats()
        self._map_q: queue.Queue[tuple[str, Any, int]] = queue.Queue(maxsize=queue_size)
        self._recv_ns = 0
        self.pipeline = Pipeline(cfg, mapping_sink=self._to_mapping)
        self._q: queue.Queue[_Item] = queue.Queue(maxsize=queue_size)
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self.drivers: dict[str, Any] = {}
        self.bus: Bus | None = None
        self.log: Any = None
        self.fake: FakeProcess | None = None
        self._cmd_lock = threading.Lock()
        self.gate = CmdVelGate(cfg.cmd_vel.limits())
        self._fault_kinds: set[tuple[str, str]] = set()
        self._next_diag = 0.0
        self._started = False
        self._stopped = False
        self.errors: list[str] = []

    # -- lifecycle ------------------------------------------------------------------------------
    def start(self) -> None:
        cfg = self.cfg
        try:
            self.bus = Bus(self.robot, self.zenoh, fleet=cfg.fleet)
        except Exception as exc:  # zenoh.ZError and friends
            raise DaemonError(f"cannot open the Zenoh session: {exc}") from None
        try:
            if cfg.simulated:
                ep = self.zenoh.listen[0] if self.zenoh.listen else None
                if ep is not None:
                    host_port = ep.split("/", 1)[1]
                    if host_port.startswith(("0.0.0.0", "[::]")):
                        ep = "tcp/127.0.0.1:" + host_port.rsplit(":", 1)[1]
                self.fake = FakeProcess(cfg, ep)
                self.cfg = cfg = cfg.with_ports(self.fake.ports)
            self._open_log()
            self.bus.subscribe(self.robot, "cmd_vel", self._on_cmd_vel)
            self.bus.subscribe(self.robot, "truth", self._on_truth)
            if cfg.services.localization.enabled:
                self.bus.subscribe("*", "pose_box", self._on_other)
            self.bus.queryable("pose", lambda: self.pipeline.latest.get("pose"))
            self.bus.queryable("map", lambda: self.pipeline.latest.get("map"))
            self.bus.queryable("info", lambda: self.pipeline.latest.get("info"))
            self.drivers = make_drivers(cfg, self._raw_hook)
            for name, drv in self.drivers.items():
                t = threading.Thread(target=self._reader, args=(name, drv), name=f"dev-{name}")
                t.daemon = True
                t.start()
                self._threads.append(t)
            self._loop_thread = threading.Thread(target=self._service_loop, name="services")
            self._loop_thread.daemon = True
            self._loop_thread.start()
            self._watchdog_thread = threading.Thread(target=self._watchdog, name="watchdog")
            self._watchdog_thread.daemon = True
            self._watchdog_thread.start()
            if self.pipeline.mapping is not None:
                self._map_thread = threading.Thread(target=self._mapping_loop, name="mapping")
                self._map_thread.daemon = True
                self._map_thread.start()
            self.bus.declare_alive()
        except BaseException:
            self.stop()
            raise
        self._started = True

    def _open_log(self) -> None:
        cfg = self.cfg
        if not cfg.log.enabled:
            return
        if self.log_path is None:
            stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
            self.log_path = Path(cfg.log.dir) / f"{cfg.name}-{stamp}.mcap"
        try:
            self.log_path.parent.mkdir(parents=True, exist_ok=True)
            meta = {
                "robot": cfg.name,
                "config": cfg.source,
                "simulated": str(self.fake is not None).lower(),
                "plan": cfg.simulation.plan if self.fake is not None else "",
                "seed": str(cfg.simulation.seed) if self.fake is not None else "",
                "services": ",".join(self.pipeline.services),
            }
            src = Path(cfg.source)
            if cfg.source != "<defaults>" and src.is_file():
                meta["config_toml"] = src.read_text(encoding="utf-8")  # for hilnav replay
            self.log = open_log_writer(self.log_path, cfg.log.compression, meta)
        except OSError as exc:
            raise DaemonError(
                f"cannot write the log {self.log_path}: {exc.strerror or exc}; set [log] dir "
                "to a writable directory"
            ) from None

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
        arcos = self.drivers.get("arcos")
        with self._cmd_lock:
            self.gate.halt()
            if arcos is not None:
                with contextlib.suppress(Exception):
                    arcos.stop()
        for t in self._threads:
            t.join(timeout=3.0)
        loop = getattr(self, "_loop_thread", None)
        if loop is not None:
            loop.join(timeout=5.0)
        self._drain()
        mt = getattr(self, "_map_thread", None)
        if mt is not None:
            self._map_q.put(("", None, 0))  # the mapping thread finishes its queue, then stops
            mt.join(timeout=10.0)
        for drv in self.drivers.values():
            with contextlib.suppress(Exception):
                drv.close()
        if self.bus is not None:
            with contextlib.suppress(Exception):
                self.bus.close()
        if self.log is not None:
            with contextlib.suppress(Exception):
                self.log.close()
        if self.fake is not None:
            self.fake.stop()

    def __enter__(self) -> Daemon:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- producers (device threads, Zenoh threads) ------------------------------------------------
    def _put(self, topic: str, msg: Any) -> None:
        try:
            self._q.put_nowait(_Item(topic, msg, time.time_ns()))
        except queue.Full:
            self.stats.dropped += 1

    def _raw_hook(self, device: str):  # noqa: ANN202
        if not self.cfg.log.raw or not self.cfg.log.enabled:
            return None

        def hook(data: bytes, stamp_ns: int) -> None:
            self._put(f"raw/{device}", RawBytes(stamp_ns, device, bytes(data), "rx"))

        return hook

    def _reader(self, name: str, drv: Any) -> None:
        try:
            drv.open()
        except Exception as exc:  # noqa: BLE001 - the driver retries in read()
            drv.last_error = str(exc)
            self.errors.append(f"{name}: {exc}")
            print(f"hilnav run: {name}: {exc} (retrying)", file=sys.stderr, flush=True)
        while not self._stop.is_set():
            try:
                got = drv.read(0.2)
            except Exception as exc:  # noqa: BLE001 - a driver bug must not kill the thread
                drv.last_error = f"read failed: {exc!r}"
                time.sleep(0.2)
                continue
            for m in got:
                topic = DEVICE_TOPICS.get(type(m))
                if topic is not None:
                    self._put(topic, m)

    def _on_cmd_vel(self, robot: str, cmd: VelocityCommand) -> None:
        arcos = self.drivers.get("arcos")
        with self._cmd_lock:
            if self._stop.is_set():
                return
            c = self.gate.accept(cmd, time.monotonic())
            self.stats.cmd_received, self.stats.cmd_rejected = (
                self.gate.received,
                self.gate.rejected,
            )
            if c is None:
                return
            if arcos is not None:
                arcos.command(c)
        self._put("cmd_vel", c)

    # -- the motion watchdog (its own thread: a stalled or dead service loop still stops) --
    def _watchdog(self) -> None:
        period = min(0.05, self.cfg.cmd_vel.timeout_s / 4, self.cfg.cmd_vel.stall_s / 4)
        while not self._stop.wait(period):
            try:
                self._check_motion(time.monotonic())
            except Exception as exc:  # noqa: BLE001 - the watchdog must outlive any fault
                self._fault("watchdog", exc)

    def _check_motion(self, now: float) -> None:
        with self._cmd_lock:
            reason = self.gate.check(now)
            if reason is None:
                return
            self.stats.cmd_timeouts, self.stats.cmd_stalls = self.gate.timeouts, self.gate.stalls
            arcos = self.drivers.get("arcos")
            if arcos is not None:
                arcos.stop()
        if reason == "stall":
            self._fault("services", RuntimeError("service loop stalled: robot stopped"))
        self._put("cmd_vel", VelocityCommand(time.time_ns(), source=f"{self.robot}/{reason}"))

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

    def _on_truth(self, robot: str, msg: Any) -> None:
        self._put("truth", msg)

    def _on_other(self, robot: str, msg: Any) -> None:
        if robot != self.robot:
            self._put(f"other/{robot}/pose_box", msg)

    # -- the mapping thread --------------------------------------------------------------------------
    def _to_mapping(self, topic: str, msg: Any) -> None:
        try:
            self._map_q.put_nowait((topic, msg, self._recv_ns))
        except queue.Full:
            self.stats.dropped += 1

    def _mapping_loop(self) -> None:
        mapping = self.pipeline.mapping
        assert mapping is not None
        while True:
            topic, msg, recv_ns = self._map_q.get()
            if msg is None:
                return
            try:
                outs = mapping.feed(topic, msg)
            except Exception as exc:  # noqa: BLE001 - a mapping bug must not stop the robot
                self._fault("mapping", exc)
                continue
            for t, m in outs:
                self.pipeline.latest[t] = m
                try:
                    self._emit(t, m, recv_ns, publish=not self._stop.is_set())
                except Exception as exc:  # noqa: BLE001
                    self._fault("mapping", exc)

    # -- the service loop --------------------------------------------------------------------------
    def _service_loop(self) -> None:
        self._next_diag = time.monotonic() + self.cfg.diagnostics_period_s
        while not self._stop.is_set():
            now = time.monotonic()
            with self._cmd_lock:
                self.gate.heartbeat(now)
            try:
                item = self._q.get(timeout=0.05)
            except queue.Empty:
                item = None
            if item is not None:
                self._handle_safely(item)
            now = time.monotonic()
            if now >= self._next_diag:
                self._next_diag = now + self.cfg.diagnostics_period_s
                try:
                    self._diagnostics()
                except Exception as exc:  # noqa: BLE001
                    self._fault("diagnostics", exc)

    def _handle_safely(self, item: _Item, publish: bool = True) -> None:
        try:
            self._handle(item, publish)
        except Exception as exc:  # noqa: BLE001 - one message must never stop the loop
            self._fault("services", exc)

    def _drain(self) -> None:
        while True:
            try:
                item = self._q.get_nowait()
            except queue.Empty:
                return
            self._handle_safely(item, publish=False)

    def _handle(self, item: _Item, publish: bool = True) -> None:
        topic, msg = item.topic, item.msg
        self.stats.processed += 1
        self.stats.by_topic[topic] = self.stats.by_topic.get(topic, 0) + 1
        if topic.startswith("other/"):
            _, robot, t = topic.split("/", 2)
            outs = self.pipeline.feed_other(robot, t, msg)
            self._log(f"/{robot}/{t}", msg, item.recv_ns)
        else:
            if topic == "info":
                self.pipeline.latest["info"] = msg
            self._emit(topic, msg, item.recv_ns, publish)
            self._recv_ns = item.recv_ns
            outs = self.pipeline.feed(topic, msg)
        for t, m in outs:
            self._emit(t, m, item.recv_ns, publish)

    def _emit(self, topic: str, msg: Any, log_ns: int, publish: bool = True) -> None:
        if publish and topic in PUBLISHED and self.bus is not None:
            try:
                self.bus.publish(topic, msg)
                self.stats.published += 1
            except Exception as exc:  # noqa: BLE001 - a bus hiccup must not stop the robot
                self._fault("bus", exc)
        self._log(f"/{self.robot}/{topic}", msg, log_ns)

    def _log(self, mcap_topic: str, msg: Any, log_ns: int) -> None:
        """Log time = when the daemon received the message (for a service output: when
        it received the input that caused it, as ``hilnav replay`` does); publish time =
        the message's own stamp (for device data the time its bytes were read)."""
        if self.log is None:
            return
        stamp = getattr(msg, "stamp_ns", None)
        if not isinstance(stamp, int) or not 0 < stamp < 2**63:
            stamp = None
        try:
            self.log.write(mcap_topic, msg, log_ns, stamp)
            self.stats.logged += 1
        except Exception as exc:  # noqa: BLE001 - a message the log refuses is counted
            self._fault("log", exc)

    def _diagnostics(self) -> None:
        stamp = time.time_ns()
        for drv in self.drivers.values():
            try:
                d = drv.diagnostics(stamp)
            except Exception as exc:  # noqa: BLE001
                d = DeviceDiagnostics(stamp, getattr(drv, "device", "?"), last_error=repr(exc))
            self._emit("diagnostics", d, stamp)
        if self.bus is not None:
            b = self.bus.stats
            self._emit(
                "diagnostics",
                DeviceDiagnostics(
                    stamp,
                    "bus",
                    connected=True,
                    frames_ok=b.received,
                    bad_checksums=b.malformed,
                    frames_lost=b.foreign,
                    last_error=b.last_problem,
                ),
                stamp,
            )
        self._emit(
            "diagnostics",
            DeviceDiagnostics(
                stamp,
                "queue",
                connected=True,
                frames_ok=self.stats.processed,
                frames_lost=self.stats.dropped,
                bad_checksums=sum(self.stats.faults.values()),
                last_error=self.errors[-1] if self.errors else "",
            ),
            stamp,
        )
