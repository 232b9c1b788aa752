"""One robot's runtime: its services, its peers, the bus and the log, fed by one queue.

The daemon (``hilnav run``) and every robot of ``hilnav fleet`` are a
:class:`RobotRuntime`; only what feeds them differs (the daemon: its device loop,
:mod:`hilnav.devloop`, which reads the devices and handles their reads itself,
:meth:`handle_read`; a fleet robot: the scenario's simulated devices, stepped by
:mod:`hilnav.fleet.host`). The runtime owns:

- the :class:`hilnav.pipeline.Pipeline` of the robot's config (its mapping worker, if
  any, hands its outputs back here), or another pipeline with its interface (``pipeline``:
  called as ``Pipeline`` is; a fleet robot replaying a data set's robot); a pipeline's
  ``shared_outputs`` are published and taken from the peers beside the pose boxes;
- ONE queue (:class:`hilnav.runtime_queue.RuntimeQueue`, its base class): :meth:`put` one
  message, :meth:`put_read` the items of one device read as ONE entry, from any thread
  (device readers, Zenoh's callbacks), taken in arrival order by one consumer
  (:meth:`next` or :meth:`take_queued`, then :meth:`handle`; or :meth:`drain`);
- the :class:`hilnav.bus.Bus` (``[zenoh]``; or on the Zenoh session of the process's
  robots: a fleet host), the fleet's pose boxes and liveliness
  tokens (:meth:`declare_peers`) and the queryables ``pose``, ``map``, ``info``;
- the :class:`hilnav.peers.PeerTable` (a peer is dropped when its token goes or its
  boxes stop for ``peer_timeout_s``; every admission and drop is kept in
  :attr:`peer_events` with the wall time it arrived);
- the sinks (:mod:`hilnav.sinks`: the MCAP log, the live view), each message encoded once
  (the bus sends the log's native record);
- the fault counters: an exception while handling one message is counted per place,
  kept for ``status`` and printed once per kind, and the runtime goes on.

A device message is logged, published when :data:`hilnav.topics.PUBLISHED` says so, and
fed to the pipeline, whose outputs are published and logged the same way the moment their
service makes them (the pipeline's ``on_output``: the pose goes out before cooperative
localization's step). A prompt item of a device read (odometry: :meth:`handle_read`'s
``prompt``) and the outputs made of it are each put on the bus at once and logged, with
their Foxglove views, after the last of them, so nothing but their own encodings comes
between the device's read and the pose's put. Log time is when the message was put on
the queue (for a service output: when its input was). :meth:`open_bus` lowers the process's GIL switch interval to
:attr:`RobotRuntime.SWITCH_INTERVAL_S`.
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from drivers.clock import CLOCK, now_ns
from hilnav.bus import Bus, ZenohSettings, zenoh_problem
from hilnav.bus_session import BusSession
from hilnav.config import RobotConfig
from hilnav.log.encoding import ViewMemo, stamp_of
from hilnav.peers import PeerTable
from hilnav.pipeline import Pipeline
from hilnav.runtime_queue import Item, RuntimeQueue, RuntimeStats, Wake
from hilnav.sinks import Sink, Sinks, default_log_path, open_run_log
from hilnav.topics import PEER_TOPICS, PUBLISHED, log_topic
from msgs import DaemonStatus

__all__ = ["Item", "PeerEvent", "RobotRuntime", "RuntimeStats", "StartError"]


class StartError(RuntimeError):
    """The runtime cannot start (Zenoh, the log directory): the message says why."""


@dataclass(frozen=True)
class PeerEvent:
    """A peer admitted or dropped, at the wall time its cause arrived."""

    wall_ns: int
    robot: str
    present: bool
    why: str


class RobotRuntime(RuntimeQueue):
    """One robot's services, peers, bus and sinks behind one queue (module docstring)."""

    # How long a thread holding the GIL keeps it while another waits (Python's default is
    # 5 ms): a reader or the service loop woken by a device read gets it from the mapping
    # thread's pure-Python steps after 0.5 ms. Set for the whole process by open_bus().
    SWITCH_INTERVAL_S = 0.0005

    def __init__(
        self,
        cfg: RobotConfig,
        *,
        zenoh: ZenohSettings | None = None,
        sinks: dict[str, Sink] | None = None,
        queue_size: int = 20000,
        prog: str = "hilnav run",
        wake: Wake | None = None,
        pipeline: Callable[..., Any] = Pipeline,
        memo: ViewMemo | None = None,
    ) -> None:
        """``memo``: the log's views shared with other robots' runtimes in this process (a
        fleet host: :class:`hilnav.log.encoding.ViewMemo`)."""
        self.cfg = cfg
        self.robot = cfg.name
        self.zenoh = zenoh or cfg.zenoh.settings()
        self.prog = prog
        super().__init__(queue_size, wake)
        self.errors: list[str] = []
        self._fault_kinds: set[tuple[str, str]] = set()
        self.pipeline = pipeline(
            cfg, on_mapping=self._from_mapping, on_fault=self.fault, on_output=self._from_service
        )
        # what the pipeline exchanges with its peers besides the pose boxes (hilnav.topics)
        shared = tuple(getattr(self.pipeline, "shared_outputs", ()))
        self._peer_topics = tuple(dict.fromkeys((*PEER_TOPICS, *shared)))
        self._published = PUBLISHED | frozenset(shared)
        self.peers = PeerTable(cfg.services.localization.peer_timeout_s)
        self.peer_events: list[PeerEvent] = []
        self._publishing = True  # the publish flag of the item being handled
        self._log_topics: dict[str, str] = {}  # topic -> /<robot>/<topic>
        self.bus: Bus | None = None
        self.log: Any = None
        self.log_path: Path | None = None
        self.sinks = Sinks(sinks or {}, self.fault, memo)  # + "log" when the log opens
        self.closing = threading.Event()  # set: outputs are logged, no longer published
        self._closed = False
        # while a prompt item is handled: what its thread put on the bus but has not
        # logged yet (mcap topic, message, native record, log time), and that thread
        self._unlogged: list[tuple[str, Any, Any, int]] | None = None
        self._unlogged_thread = 0

    # -- opening ------------------------------------------------------------------------------
    def open_bus(self, shared: BusSession | None = None) -> Bus:
        """The robot's bus on a Zenoh session of its own (``[zenoh]``), or on ``shared``,
        the session of the process's robots (a fleet host)."""
        sys.setswitchinterval(min(sys.getswitchinterval(), self.SWITCH_INTERVAL_S))
        try:
            self.bus = Bus(self.robot, self.zenoh, fleet=self.cfg.fleet, shared=shared)
        except Exception as exc:  # zenoh.ZError and friends
            raise StartError(f"cannot open the Zenoh session: {zenoh_problem(exc)}") from None
        return self.bus

    def open_log(
        self, path: str | Path | None, *, simulated: bool, metadata: dict[str, str] | None = None
    ) -> None:
        """The MCAP log at ``path`` (default: ``[log] dir/<robot>-<UTC>.mcap``) as the
        sink "log"; nothing when ``[log] enabled`` is false."""
        if not self.cfg.log.enabled:
            return
        self.log_path = Path(path) if path else default_log_path(self.cfg)
        try:
            self.log = open_run_log(
                self.cfg, self.log_path, simulated=simulated, services=self.pipeline.services
            )
        except OSError as exc:
            raise StartError(
                f"cannot write the log {self.log_path}: {exc.strerror or exc}; set [log] dir "
                "to a writable directory"
            ) from None
        if metadata:
            self.log.add_metadata("scenario", metadata)
        self.sinks.add("log", self.log)

    def declare_peers(self) -> None:
        """The fleet's pose boxes (the peer topics and the pipeline's shared outputs) and
        liveliness (when localization runs) onto the queue, and the queryables ``pose``,
        ``map``, ``info``."""
        assert self.bus is not None
        if self.cfg.services.localization.enabled:
            for topic in self._peer_topics:
                self.bus.subscribe("*", topic, lambda r, m, t=topic: self._on_peer(r, t, m))
            self.bus.on_liveliness(self._on_liveliness)
        latest = self.pipeline.latest
        for name in ("pose", "map", "info"):
            self.bus.queryable(name, lambda n=name: latest.get(n))

    def close(self) -> None:
        """Let the mapping worker finish (its outputs logged), log the services' last
        outputs (the final map: :meth:`hilnav.pipeline.Pipeline.finish`), close the bus
        and sinks."""
        if self._closed:
            return
        self._closed = True
        self.closing.set()
        self.pipeline.close()
        finish = getattr(self.pipeline, "finish", None)  # (a data set's pipeline has none)
        if finish is not None:
            self.guard("mapping", finish)  # its outputs: logged by _from_service
        if self.bus is not None:
            try:
                self.bus.close()
            except Exception as exc:
                self.fault("bus", exc)
        self.sinks.close()

    # -- producers (any thread) -------------------------------------------------------------------
    def _on_peer(self, robot: str, topic: str, msg: Any) -> None:
        if robot != self.robot:
            self.put(topic, msg, peer=robot)

    def _on_liveliness(self, robot: str, alive: bool) -> None:
        if robot != self.robot:
            self.put("", alive, peer=robot)

    def _from_mapping(self, topic: str, msg: Any, recv_ns: Any) -> None:
        self.emit(topic, msg, int(recv_ns or now_ns()), publish=not self.closing.is_set())

    def _from_service(self, topic: str, msg: Any, recv_ns: Any) -> None:
        """A service's output, the moment it is made (the pose before CP runs)."""
        publish = self._publishing and not self.closing.is_set()
        self.emit(topic, msg, int(recv_ns or now_ns()), publish)

    def fault(self, where: str, exc: BaseException) -> None:
        """Count a fault, keep it for ``status``, print its first occurrence per kind."""
        self.stats.faults[where] = self.stats.faults.get(where, 0) + 1
        text = f"{where}: {exc!r}"
        self.errors.append(text)
        del self.errors[:-100]
        kind = (where, type(exc).__name__)
        if kind not in self._fault_kinds:
            self._fault_kinds.add(kind)
            print(f"{self.prog}: {text} (counted; the loop goes on)", file=sys.stderr, flush=True)

    # -- the consumer (one thread) ------------------------------------------------------------------
    def drain(self, publish: bool = True) -> int:
        """Handle everything queued now; how many items."""
        n = 0
        for entry in self.take_queued():
            self.handle(entry, publish)
            n += len(entry) if type(entry) is list else 1
        return n

    def handle_read(
        self,
        pending: list[tuple[str, Any]],
        recv_ns: int | None = None,
        publish: bool = True,
        later: list[tuple[str, Any, int]] | None = None,
        prompt: frozenset[str] = frozenset(),
    ) -> None:
        """One device read's ``(topic, msg)`` items, received at ``recv_ns`` (default now),
        handled by the consumer's thread (the daemon's loop reads devices itself). With
        ``later``, the items go to the services now but are logged and published by
        :meth:`emit_later`, except those of a ``prompt`` topic (odometry, before its pose)."""
        now = now_ns() if recv_ns is None else recv_ns
        for topic, msg in pending:
            try:
                if topic in prompt:
                    self._handle_prompt(topic, msg, now, publish)
                elif later is None:
                    self._handle_own(topic, msg, now, publish)
                else:
                    later.append((topic, msg, now))
                    self._handle_own(topic, msg, now, publish, False)
            except Exception as exc:
                self.fault("services", exc)

    def _handle_prompt(self, topic: str, msg: Any, recv_ns: int, publish: bool) -> None:
        """A prompt item (odometry) and the outputs made of it (heading, pose, box): each
        goes on the bus the moment it is made, and all are logged, with their Foxglove
        views, after the last: neither the views' encoding nor a log write (at times a
        chunk's compression) comes between the device's read and the pose's put."""
        if not self.sinks or not self.sinks.splits:
            self._handle_own(topic, msg, recv_ns, publish)
            return
        self._unlogged, self._unlogged_thread = [], threading.get_ident()
        try:
            self._handle_own(topic, msg, recv_ns, publish)
        finally:
            unlogged, self._unlogged = self._unlogged, None
            for mcap_topic, out, native, log_ns in unlogged:
                self.guard("log", self._log_native, mcap_topic, out, native, log_ns)

    def _log_native(self, mcap_topic: str, msg: Any, native: Any, log_ns: int) -> None:
        """Log a message already put on the bus: its native record, then its views."""
        records = [native, *self.sinks.views(mcap_topic, msg)]
        if self.sinks.write_records(records, log_ns, stamp_of(msg)):
            self.stats.logged += 1

    def emit_later(self, later: list[tuple[str, Any, int]], publish: bool = True) -> None:
        """Log and publish the items :meth:`handle_read` left for later, in order."""
        for topic, msg, recv_ns in later:
            self.guard("services", self.emit, topic, msg, recv_ns, publish)

    def guard(self, where: str, fn: Any, *args: Any) -> None:
        """``fn(*args)``, an exception counted under ``where``."""
        try:
            fn(*args)
        except Exception as exc:
            self.fault(where, exc)

    def handle(self, entry: Item | list[Item], publish: bool = True) -> None:
        """One queue entry (an item, or one device read's items in order) through the
        services, the bus and the sinks (faults counted per item)."""
        if type(entry) is list:
            for item in entry:
                self.guard("services", self._handle, item, publish)
        else:
            self.guard("services", self._handle, entry, publish)

    def expire_peers(self, now: float | None = None) -> None:
        """Drop the peers silent for longer than ``peer_timeout_s``."""
        now = time.monotonic() if now is None else now
        gone = self.peers.expire(now)
        for robot, (_, why) in zip(
            gone, self.peers.dropped[len(self.peers.dropped) - len(gone) :], strict=True
        ):
            self._peer_event(now_ns(), robot, False, why)
            self.guard("services", self.pipeline.drop_peer, robot)

    def _handle(self, item: Item, publish: bool) -> None:
        if item.peer:
            self.stats.processed += 1
            self.stats.by_topic[item.topic] = self.stats.by_topic.get(item.topic, 0) + 1
            self._handle_peer(item)
            return
        self._handle_own(item.topic, item.msg, item.recv_ns, publish)

    def _handle_own(
        self, topic: str, msg: Any, recv_ns: int, publish: bool, emit: bool = True
    ) -> None:
        stats = self.stats
        stats.processed += 1
        stats.by_topic[topic] = stats.by_topic.get(topic, 0) + 1
        if topic == "info":
            self.pipeline.latest["info"] = msg
        if emit:
            self.emit(topic, msg, recv_ns, publish)
        self._publishing = publish
        try:
            self.pipeline.feed(topic, msg, recv_ns)  # outputs: self._from_service
        finally:
            self._publishing = True

    def _handle_peer(self, item: Item) -> None:
        now = time.monotonic()
        if not item.topic:  # a liveliness change
            was = item.peer in self.peers.last_seen
            if self.peers.token(item.peer, bool(item.msg), now):
                self._peer_event(item.recv_ns, item.peer, False, "token gone")
                self.pipeline.drop_peer(item.peer)
            elif item.msg and not was:
                self._peer_event(item.recv_ns, item.peer, True, "token")
            return
        if self.peers.seen(item.peer, now):
            self._peer_event(item.recv_ns, item.peer, True, "data")
        self.log_msg(log_topic(item.peer, item.topic), item.msg, item.recv_ns)
        for t, m in self.pipeline.feed_other(item.peer, item.topic, item.msg):
            self.emit(t, m, item.recv_ns)

    def _peer_event(self, wall_ns: int, robot: str, present: bool, why: str) -> None:
        self.peer_events.append(PeerEvent(wall_ns, robot, present, why))
        del self.peer_events[:-10000]

    def emit(self, topic: str, msg: Any, log_ns: int, publish: bool = True) -> None:
        """Publish (if the topics table says so) and log one of this robot's messages,
        encoded once: the bus sends the log's native record (its own encoding when there
        is no sink). Log and publish times as in :meth:`log_msg`. While the loop handles a
        prompt item, its thread's messages are logged after it (:meth:`_handle_prompt`)."""
        records = None
        unlogged = self._unlogged
        if unlogged is not None and self._unlogged_thread != threading.get_ident():
            unlogged = None  # (the mapping worker's output, while the loop handles odometry)
        if self.sinks:
            mcap_topic = self._log_topics.get(topic)
            if mcap_topic is None:
                mcap_topic = self._log_topics[topic] = log_topic(self.robot, topic)
            if unlogged is None:
                records = self.sinks.encode(mcap_topic, msg)
            else:
                native = self.sinks.encode_native(mcap_topic, msg)
                records = None if native is None else [native]
        if publish and topic in self._published and self.bus is not None:
            try:
                if records:
                    native = records[0]
                    self.bus.put_encoded(self.robot, topic, native.data, native.schema_name)
                else:
                    self.bus.publish(topic, msg)
                self.stats.published += 1
            except Exception as exc:
                self.fault("bus", exc)
        if records:
            if unlogged is not None:
                unlogged.append((mcap_topic, msg, records[0], log_ns))  # logged after the read
            elif self.sinks.write_records(records, log_ns, stamp_of(msg)):
                self.stats.logged += 1

    def log_msg(self, mcap_topic: str, msg: Any, log_ns: int) -> None:
        """To every sink (log, live view). Log time = when the message was queued (for a
        service output: when its input was, as ``hilnav replay`` does); publish time = the
        message's own stamp (for device data the time its bytes were read)."""
        if self.sinks and self.sinks.write(mcap_topic, msg, log_ns):
            self.stats.logged += 1

    def status(self, stamp_ns: int, **more: Any) -> DaemonStatus:
        """The runtime's health counters (msgs.DaemonStatus); ``more`` adds fields (the
        daemon's motion gate)."""
        b = self.bus.stats if self.bus is not None else None
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
            clock_back_steps=CLOCK.back_steps,
            clock_forward_steps=CLOCK.forward_steps,
            **more,
        )
