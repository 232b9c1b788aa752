"""One Zenoh session and its subscriptions, for one :class:`hilnav.bus.Bus` or shared by
the buses of several robots in one process (the robots of a ``hilnav fleet`` host).

Each bus keeps its own robot name, publishers, sender attachment, liveliness token,
queryables, fleet filter and counters; the session owns the subscriptions: ONE Zenoh
subscriber per key expression and ONE liveliness subscriber however many buses subscribe,
each sample's key, sender and payload worked out once (:class:`Payload`) and handed to
every bus that subscribed (:meth:`hilnav.bus.Bus.deliver`: its fleet check, its counters,
its callback). A bus that subscribes to liveliness after the subscriber was declared is
told of the tokens present then (Zenoh's ``history``, kept here).

A session may be ``deferred`` (a fleet host): the samples wait in Zenoh's own ring
channel, and the thread that steps the robots hands them to the buses when it looks
(:meth:`BusSession.pump`). No Python callback runs for them, so no other thread takes the
GIL from the stepping thread: each callback's thread did, at every sample, and the
stepping thread then waited for the GIL back (on a loaded machine, for a time slice).
Liveliness changes (rare) still come by callback.

Why share: with a session per robot, a host of n robots in a fleet of N receives every
peer sample n times (the router sends it to each session) and zenoh-python runs each
callback on a Python thread of its own, which must take the GIL from the thread that
steps the robots: N x n wake-ups per step. One session per host: N, decoded once.
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Any

import zenoh

import msgs
from hilnav.topics import topic_type

if TYPE_CHECKING:
    from collections.abc import Callable

    from hilnav.bus import Bus

LIVELINESS_KEY = "hilnav/*/alive"
# samples a deferred subscription holds (Zenoh drops the oldest beyond: never blocks)
INBOX = 1 << 16
_UNSET: Any = object()


class Payload:
    """A received sample's key, sender and message, each worked out once however many
    buses take the sample."""

    __slots__ = ("_sample", "_head", "_cls", "_msg", "_error")

    def __init__(self, sample: zenoh.Sample) -> None:
        self._sample = sample
        self._head: Any = _UNSET
        self._cls: type | None = None
        self._msg: Any = _UNSET
        self._error: Exception | None = None

    def head(self) -> tuple[str, str, str] | None:
        """(robot of the key ``hilnav/<robot>/<topic>``, topic, sender from the
        attachment), or None when the key is no hilnav topic."""
        if self._head is _UNSET:
            parts = str(self._sample.key_expr).split("/")
            src, topic = (parts[1], "/".join(parts[2:])) if len(parts) > 2 else ("", "")
            self._cls = topic_type(topic)
            if self._cls is None:
                self._head = None
            else:
                att = self._sample.attachment
                sender = att.to_bytes().decode("utf-8", "replace") if att is not None else ""
                self._head = (src, topic, sender)
        return self._head

    def msg(self) -> Any:
        """The decoded message (after :meth:`head`); the decoding error (msgs.DecodeError)
        raised again for every bus that asks."""
        if self._error is not None:
            raise self._error
        if self._msg is _UNSET:
            assert self._cls is not None
            try:
                self._msg = msgs.decode(self._cls, self._sample.payload.to_bytes())
            except Exception as exc:
                self._error = exc
                raise
        return self._msg


Target = tuple["Bus", Any]


class Subscription:
    """A bus's subscription on a :class:`BusSession` (``undeclare()`` ends it)."""

    def __init__(self, session: BusSession, keyexpr: str | None, target: Target) -> None:
        self._session, self._keyexpr, self._target = session, keyexpr, target

    def undeclare(self) -> None:
        self._session._remove(self._keyexpr, self._target)


class BusSession:
    """A Zenoh session and its subscriptions (module docstring). ``close()`` undeclares
    the subscribers and closes the session."""

    def __init__(self, config: Any, *, deferred: bool = False) -> None:
        """``config``: a :class:`hilnav.bus.ZenohSettings` or a ``zenoh.Config``.
        ``deferred``: the samples wait in Zenoh's own channel (no Python callback) until
        :meth:`pump`, in the consumer's thread, hands them to the buses."""
        cfg = config.to_zenoh() if hasattr(config, "to_zenoh") else config
        self.session = zenoh.open(cfg)
        self.deferred = deferred
        self._channels: tuple[tuple[str, Any], ...] = ()  # (key expression, subscriber)
        self._lock = threading.Lock()
        self._targets: dict[str, tuple[Target, ...]] = {}  # key expression -> buses
        self._subscribers: dict[str, Any] = {}
        self._live_targets: tuple[Target, ...] = ()
        self._live_sub: Any = None
        self._alive: set[str] = set()  # liveliness keys present (for late subscribers)
        self.samples = 0  # samples received (each once, however many buses took it)
        self._closed = False

    # -- data ------------------------------------------------------------------------------
    def subscribe(
        self, keyexpr: str, bus: Bus, callback: Callable[[str, str, Any], None]
    ) -> Subscription:
        """``bus.deliver(sample, payload, callback)`` for each sample on ``keyexpr``."""
        target = (bus, callback)
        with self._lock:
            self._targets[keyexpr] = (*self._targets.get(keyexpr, ()), target)
            declare = keyexpr not in self._subscribers
            if declare:
                self._subscribers[keyexpr] = None  # being declared (outside the lock)
        if declare:
            if self.deferred:  # Zenoh's thread never takes the GIL for these samples
                sub = self.session.declare_subscriber(keyexpr, zenoh.handlers.RingChannel(INBOX))
            else:
                sub = self.session.declare_subscriber(
                    keyexpr, lambda sample: self._deliver(keyexpr, sample)
                )
            with self._lock:
                self._subscribers[keyexpr] = sub
                if self.deferred:
                    self._channels = (*self._channels, (keyexpr, sub))
        return Subscription(self, keyexpr, target)

    def _deliver(self, keyexpr: str, sample: zenoh.Sample) -> None:
        self.samples += 1
        payload = Payload(sample)
        for b, cb in self._targets.get(keyexpr, ()):
            b.deliver(sample, payload, cb)

    def pump(self) -> int:
        """Hand the samples received so far to the buses (``deferred``), each key
        expression's in arrival order; how many."""
        n = 0
        for keyexpr, sub in self._channels:
            while (sample := sub.try_recv()) is not None:
                self._deliver(keyexpr, sample)
                n += 1
        return n

    # -- liveliness --------------------------------------------------------------------------
    def on_liveliness(self, bus: Bus, callback: Callable[[str, bool], None]) -> Subscription:
        """``bus.liveliness(key, alive, callback)`` for every token of ``hilnav/*/alive``
        present now (as Zenoh's ``history``) and for each one appearing or going."""
        target = (bus, callback)
        with self._lock:
            self._live_targets = (*self._live_targets, target)
            for k in sorted(self._alive):
                bus.liveliness(k, True, callback)
            declare = self._live_sub is None
            if declare:
                self._live_sub = _UNSET  # being declared (outside the lock)
        if declare:
            sub = self.session.liveliness().declare_subscriber(
                LIVELINESS_KEY, self._on_live, history=True
            )
            with self._lock:
                self._live_sub = sub
        return Subscription(self, None, target)

    def _on_live(self, sample: zenoh.Sample) -> None:
        k, alive = str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT
        with self._lock:  # one order for the replay to late subscribers and the changes
            if alive:
                self._alive.add(k)
            else:
                self._alive.discard(k)
            for b, cb in self._live_targets:
                b.liveliness(k, alive, cb)

    # -- ending ------------------------------------------------------------------------------
    def _remove(self, keyexpr: str | None, target: Target) -> None:
        with self._lock:
            if keyexpr is None:
                self._live_targets = tuple(t for t in self._live_targets if t is not target)
            else:
                left = tuple(t for t in self._targets.get(keyexpr, ()) if t is not target)
                self._targets[keyexpr] = left

    def close(self) -> None:
        """Undeclare the subscribers and close the session (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            subs = [s for s in (*self._subscribers.values(), self._live_sub) if s is not None]
            self._targets.clear()
            self._live_targets = ()
        for s in subs:
            if s is _UNSET:
                continue
            try:
                s.undeclare()
            except zenoh.ZError:
                pass
        self.session.close()
