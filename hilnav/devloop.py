"""The daemon's one loop: every device port and the runtime's queue on one selector.

One thread waits on an epoll over the descriptors of the devices whose link is up and
has one (``driver.fileno()``: serial ports and ptys, the slcan adapter's port) and over
a wake-up pipe of the runtime's queue. A readable device is read at once
(``driver.read(0)``: what is there, decoded, stamped with the read's time) and its raw
bytes and messages go to the services in the same thread and the same wake-up
(:meth:`hilnav.runtime.RobotRuntime.handle_read`): one thread woken per device read
instead of a reader and a service loop, no hand-over through a queue, no reader threads
contending for the GIL. Service outputs are published and logged the moment they are
made; the device messages themselves are logged and published in batches, at most
``batch_s`` after their read (or at the loop's next tick), except those of
``prompt_topics`` (odometry, which goes out before the pose made of it): handling a lone
message costs several times as much as handling it among others on a loaded machine.

What other threads produce (Zenoh's callbacks: commands, peers' boxes, the truth; the
watchdog's stops) is queued. The loop takes the queue before each read and at each tick,
so everything is handled by one consumer in arrival order; a queue entry that must not
wait (a device thread's read, below) also wakes the loop through the pipe.

A device of ``polled`` (the daemon's: every device but the Pioneer, whose SIP releases
the pose) does not wake the loop: its descriptor sits on a second epoll that the loop asks,
without waiting, at every turn, and what it holds is read before the turn's other reads
(so the gyro's packets up to a SIP come before the SIP). The loop turns at least every
``tick_s`` (plus ``slack_s``) anyway, for its timers, so a polled device is read in
batches of that age at most: the 100 Hz gyro's packets come five at a time, and the
loop wakes about 30 times a second (SIPs, ticks) instead of about 150. The gyro's codec
stamps the packets of one read back one period apart, as the gyro sent them
(drivers.cruzcore); a port with more than a read's worth is read again in the turn, at
most ``POLL_ROUNDS`` times.

A device without a descriptor to wait on (a pyserial URL such as ``socket://``, a file of
recorded bytes, a python-can interface other than slcan) and a device whose link is down
are read by a thread of their own, as before: a blocking ``read(timeout)`` in a loop, the
driver reconnecting itself (an ARCOS handshake takes up to seconds, which the loop must
not wait for), the reads put on the queue. The moment such a device's link is up with a
descriptor the thread hands it to the loop and ends; the moment the loop sees a device's
link go (after a read), it takes the descriptor off the epoll and starts a thread for it
again. So a device is read by exactly one thread at any time.

Timers, all on the loop's own clock (no thread of their own): each looped device is
read once every ``keepalive_s`` even when silent (its keep-alive, e.g. the ARCOS PULSE,
and its silence check, which drops a dead link); the loop's heartbeat to the motion
watchdog at least every ``beat_s`` (the loop wakes for it when nothing else comes); and
the callers' periodic work (``on_tick``: peer expiry, diagnostics) every ``tick_s``. A
timer that falls due waits up to ``slack_s`` for the next device read to wake the loop
(a SIP's, every 0.1 s) instead of waking it on its own.
"""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
from collections.abc import Callable
from typing import Any

from drivers.clock import now_ns

PendingItems = list[tuple[str, Any]]
POLL_ROUNDS = 8  # reads of a polled device in one turn at most (8 x 4 KiB: ~1 MB/s at 30 Hz)


class WakePipe:
    """``set()`` from any thread wakes the loop's selector (one byte per wake-up, not per
    call: a wake-up already pending is not repeated); ``clear()`` in the loop takes it,
    before the loop looks at what it announced."""

    def __init__(self) -> None:
        self.rfd, self.wfd = os.pipe()
        os.set_blocking(self.rfd, False)
        os.set_blocking(self.wfd, False)
        self._pending = False
        self._closed = False
        self._lock = threading.Lock()

    def set(self) -> None:
        if self._pending:
            return
        with self._lock:  # never a write to a descriptor close() gave back
            if self._closed or self._pending:
                return
            self._pending = True
            with contextlib.suppress(OSError):
                os.write(self.wfd, b"\0")

    def is_set(self) -> bool:
        """A wake-up is pending (``threading.Event``'s name: producers skip a set)."""
        return self._pending

    def clear(self) -> None:
        with contextlib.suppress(OSError):
            os.read(self.rfd, 4096)
        self._pending = False  # after the read: a set() from now on writes again

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            for fd in (self.rfd, self.wfd):
                with contextlib.suppress(OSError):
                    os.close(fd)


class DeviceLoop:
    """The loop (see the module docstring). ``run()`` in the loop thread until ``stop``.

    ``runtime`` is the :class:`hilnav.runtime.RobotRuntime` whose queue and consumer the
    loop is. ``read_device(name, driver, timeout_s)`` is the daemon's read of one device
    (``driver.read`` and its raw bytes: the items of one read); ``prompt_topics`` are
    logged and published at once; ``start_thread(name, driver)`` reads a
    device by a thread until :meth:`adopt` takes it back; ``heartbeat()`` and
    ``on_tick(now)`` are called as the module docstring says."""

    def __init__(
        self,
        runtime: Any,
        *,
        read_device: Callable[[str, Any, float], PendingItems],
        prompt_topics: frozenset[str],
        start_thread: Callable[[str, Any], None],
        heartbeat: Callable[[], None],
        on_tick: Callable[[float], None],
        stop: threading.Event,
        keepalive_s: float = 0.2,
        beat_s: float = 0.1,
        tick_s: float = 0.05,
        batch_s: float = 0.1,
        slack_s: float = 0.02,
        polled: frozenset[str] = frozenset(),
    ) -> None:
        self.runtime = runtime
        self.read_device = read_device
        self.prompt_topics = prompt_topics
        self.start_thread = start_thread
        self.heartbeat = heartbeat
        self.on_tick = on_tick
        self.stop = stop
        self.keepalive_s = keepalive_s
        self.beat_s = beat_s
        self.tick_s = tick_s
        self.batch_s = batch_s
        self.slack_s = slack_s
        self.polled = polled
        self.wake = WakePipe()
        self._poller = select.epoll()  # (select.poll would busy-loop on a regular file)
        self._poller.register(self.wake.rfd, select.EPOLLIN)
        self._by_fd: dict[int, tuple[str, Any]] = {}
        self._poll_later = select.epoll()  # the polled devices' descriptors: never waited on
        self._polled_fds: set[int] = set()
        self._adopted: list[tuple[str, Any]] = []  # handed over by threads, not yet looped
        self._adopt_lock = threading.Lock()
        # name -> [driver, its descriptor, monotonic time of its last read]
        self._looped: dict[str, list[Any]] = {}
        # the read items given to the services but not logged and published yet, in
        # order: (topic, msg, receive time ns); the monotonic time of the first
        self._backlog: list[tuple[str, Any, int]] = []
        self._backlog_since = 0.0
        self._next_tick = self._next_keep = self._last_beat = 0.0  # set by run()
        self.reads = 0  # device reads done by the loop
        self.batches = 0  # backlogs logged and published
        self.handovers = 0  # devices the loop gave to a thread (link down)

    # -- any thread ---------------------------------------------------------------------
    def adopt(self, name: str, driver: Any) -> None:
        """A device thread hands its device (link up, with a descriptor) to the loop."""
        with self._adopt_lock:
            self._adopted.append((name, driver))
        self.wake.set()

    @property
    def looped(self) -> list[str]:
        """The devices the loop reads now."""
        return list(self._looped)

    # -- the loop thread --------------------------------------------------------------------
    def run(self) -> None:
        try:
            self._run()
        finally:
            for name in list(self._looped):
                self._unregister(name)
            self._poll_later.close()
            self._poller.close()  # the wake pipe is closed by the owner, after the producers

    def _run(self) -> None:
        """Turns of the loop until ``stop``; a turn that raises (a driver, the log, the bus,
        a timer) is counted under ``loop`` and the next turn goes on: no single input may
        stop the loop that feeds the motion watchdog's heartbeat."""
        self._next_tick = self._next_keep = self._last_beat = time.monotonic()
        self._last_beat -= min(0.02, self.beat_s / 2)
        try:
            while not self.stop.is_set():
                try:
                    self._turn()
                except Exception as exc:
                    self.runtime.fault("loop", exc)
        finally:
            self.flush()

    def _turn(self) -> None:
        """One turn: the heartbeat, a wait for reads (bounded by the timers), the reads,
        then the timers that are due."""
        looped, by_fd = self._looped, self._by_fd
        now = time.monotonic()
        if now - self._last_beat >= min(0.02, self.beat_s / 2):
            self.heartbeat()
            self._last_beat = now
        due = min(self._next_tick, self._next_keep)
        if self._backlog:
            due = min(due, self._backlog_since + self.batch_s)
        # timers wait up to slack_s for a device's wake-up rather than make their own
        timeout = min(max(0.0, due - now) + self.slack_s, self.beat_s)
        events = self._poller.poll(timeout)
        if self._polled_fds:  # the polled devices first: the gyro up to a SIP before it
            self._read_polled()
        for fd, _ in events:
            if fd == self.wake.rfd:  # a prompt queue entry (a device thread's read)
                self.wake.clear()
                if self._adopted:
                    self._take_adopted()
                self.flush()
                continue
            entry = by_fd.get(fd)
            if entry is not None and entry[0] in looped:
                self._read(entry[0], entry[1])
        now = time.monotonic()
        if self._backlog and now - self._backlog_since >= self.batch_s:
            self.flush()
        if now >= self._next_keep:
            self._next_keep = now + self.keepalive_s
            for name, (drv, _, last) in list(looped.items()):
                if now - last >= self.keepalive_s:
                    self._read(name, drv)
        if now >= self._next_tick:
            self._next_tick = now + self.tick_s
            self.flush()
            self.on_tick(now)

    def _read_polled(self) -> None:
        """Read the polled devices that have bytes, again while they still have (a port
        that delivers more than a read takes between two turns, as a busy CAN bus can),
        at most ``POLL_ROUNDS`` times in a turn."""
        by_fd, looped = self._by_fd, self._looped
        for _ in range(POLL_ROUNDS):
            ready = self._poll_later.poll(0)
            if not ready:
                return
            for fd, _ in ready:
                entry = by_fd.get(fd)
                if entry is not None and entry[0] in looped:
                    self._read(entry[0], entry[1])

    def _absorb(self) -> None:
        """Handle what the queue holds (it came before what the loop reads next)."""
        rt = self.runtime
        if rt.queued():
            for entry in rt.take_queued():
                rt.handle(entry)

    def flush(self) -> None:
        """Handle the queue; log and publish the backlog."""
        self._absorb()
        backlog = self._backlog
        if backlog:
            self._backlog = []
            self.batches += 1
            self.runtime.emit_later(backlog)

    def _read(self, name: str, drv: Any) -> None:
        """Read one device; a read that raises is counted under ``loop``, so a device
        that always fails cannot starve the others of the turn."""
        try:
            self._read_one(name, drv)
        except Exception as exc:
            self.runtime.fault("loop", exc)

    def _read_one(self, name: str, drv: Any) -> None:
        entry = self._looped[name]
        for _ in range(64):  # bytes buffered in the driver (slcan lines): read again
            entry[2] = time.monotonic()
            self.reads += 1
            items = self.read_device(name, drv, 0.0)
            if items:
                self._absorb()
                backlog = self._backlog
                if not backlog:
                    self._backlog_since = entry[2]
                self.runtime.handle_read(items, now_ns(), later=backlog,
                                         prompt=self.prompt_topics)  # fmt: skip
            if not getattr(drv, "buffered", _false)():
                break
        fd = drv.fileno()
        if fd != entry[1]:  # the link went (or came back on another descriptor)
            self._unregister(name)
            self.handovers += 1
            self.start_thread(name, drv)

    def _take_adopted(self) -> None:
        with self._adopt_lock:
            adopted, self._adopted = self._adopted, []
        for name, drv in adopted:
            fd = drv.fileno()
            try:
                if fd is None or fd in self._by_fd:
                    raise ValueError("no descriptor of its own")
                if name in self.polled:
                    self._poll_later.register(fd, select.EPOLLIN)
                    self._polled_fds.add(fd)
                else:
                    self._poller.register(fd, select.EPOLLIN)
            except (ValueError, OSError):
                self.start_thread(name, drv)  # not selectable after all: a thread reads it
                continue
            self._by_fd[fd] = (name, drv)
            self._looped[name] = [drv, fd, time.monotonic()]
            self._read(name, drv)  # what came between the hand-over and now

    def _unregister(self, name: str) -> None:
        entry = self._looped.pop(name, None)
        if entry is None:
            return
        self._by_fd.pop(entry[1], None)
        poller = self._poller
        if entry[1] in self._polled_fds:
            self._polled_fds.discard(entry[1])
            poller = self._poll_later
        with contextlib.suppress(ValueError, OSError):  # closed with the link: gone already
            poller.unregister(entry[1])


def _false() -> bool:
    return False
