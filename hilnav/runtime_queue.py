"""The ONE queue of a robot's runtime (:class:`hilnav.runtime.RobotRuntime`): what its
producers put on it from any thread (device readers, Zenoh's callbacks, a fleet host's
step) and how its one consumer takes it.

A ``queue.SimpleQueue`` (put and get in C, no Python-level condition per message; the
bound, beyond which messages are counted as dropped, checked on its size): :meth:`put`
one message, :meth:`put_read` the items of one device read (its raw bytes, then its
messages) as ONE entry, taken in arrival order by :meth:`next` or :meth:`take_queued`.
``wake.set()`` on every put but of the ``lazy`` topics (a consumer serving several
runtimes, a fleet host, waits on one event).
"""

from __future__ import annotations

import queue
from dataclasses import dataclass, field
from typing import Any, Protocol

from drivers.clock import now_ns


class Wake(Protocol):
    """What a queue sets to wake its consumer: ``threading.Event`` (a fleet host's
    stepping thread) or ``hilnav.devloop.WakePipe`` (the daemon's device loop)."""

    def set(self) -> None: ...

    def is_set(self) -> bool: ...


@dataclass(slots=True)
class Item:
    """One queued message: ``peer`` is set for another robot's (its topic "" for a
    liveliness change, ``msg`` then True/False)."""

    topic: str
    msg: Any
    recv_ns: int
    peer: str = ""


@dataclass
class RuntimeStats:
    """What the runtime did (read by the bench and the tests)."""

    processed: int = 0
    published: int = 0
    logged: int = 0  # taken by every sink (the log, the live view)
    dropped: int = 0
    by_topic: dict[str, int] = field(default_factory=dict)
    faults: dict[str, int] = field(default_factory=dict)


class RuntimeQueue:
    """The queue, its producers (any thread) and its consumer's takes (one thread)."""

    def __init__(self, queue_size: int, wake: Wake | None) -> None:
        self.stats = RuntimeStats()
        self.wake = wake  # set on every put (a consumer serving several runtimes waits on it)
        # topics whose put() does not set ``wake`` (the consumer takes them at its next turn)
        self.lazy: frozenset[str] = frozenset()
        self._q: queue.SimpleQueue[Item | list[Item]] = queue.SimpleQueue()
        self._queue_size = queue_size

    # -- producers (any thread) -------------------------------------------------------------
    def put(self, topic: str, msg: Any, peer: str = "", recv_ns: int | None = None) -> None:
        """Queue a message (counted as dropped when the queue is full)."""
        if self._q.qsize() >= self._queue_size:
            self.stats.dropped += 1
        else:
            self._q.put(Item(topic, msg, recv_ns or now_ns(), peer))
        wake = self.wake  # (queued first: a consumer that clears it then takes the item)
        if wake is not None and topic not in self.lazy and not wake.is_set():
            wake.set()

    def put_read(self, pending: list[tuple[str, Any]]) -> None:
        """The ``(topic, msg)`` items of one device read (its raw bytes, then its messages)
        as one queue entry, received at one time: one hand-over to the consumer per read
        (all counted as dropped when the queue is full)."""
        if self._q.qsize() >= self._queue_size:
            self.stats.dropped += len(pending)
        else:
            now = now_ns()
            self._q.put([Item(topic, msg, now) for topic, msg in pending])
        if self.wake is not None and not self.wake.is_set():
            self.wake.set()

    # -- the consumer (one thread) -----------------------------------------------------------
    def next(self, timeout_s: float) -> Item | list[Item] | None:
        """The next queue entry (an item, or the items of one device read), or None after
        ``timeout_s``."""
        try:
            return self._q.get(timeout=timeout_s) if timeout_s > 0 else self._q.get_nowait()
        except queue.Empty:
            return None

    def queued(self) -> int:
        """Entries waiting in the queue."""
        return self._q.qsize()

    def take_queued(self) -> list[Item | list[Item]]:
        """The entries queued now, taken out of the queue in order."""
        out: list[Item | list[Item]] = []
        get = self._q.get_nowait
        for _ in range(self._q.qsize()):
            try:
                out.append(get())
            except queue.Empty:
                break
        return out
