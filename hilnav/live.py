"""Live view: hilnav's channels served on the Foxglove WebSocket protocol as they happen.

:class:`LiveBridge` runs a Foxglove WebSocket server (the ``foxglove-sdk`` package, its
own context so nothing else logs into it) and is a :class:`hilnav.log.encoding.Sink`: it
serves exactly the records the MCAP log gets, the native ``/<robot>/<topic>`` channels
(``hilnav.<Class>`` JSON) and the Foxglove views, one channel per topic, advertised
when its first message comes. ``hilnav run --foxglove`` adds one to the daemon's sinks;
``hilnav view`` (:func:`serve_bus`) feeds one from a Zenoh session that subscribes to
``hilnav/*/**``, so it shows every robot on the bus, and logs played by ``hilnav play``.

Clients speak the Foxglove WebSocket protocol (subprotocol ``foxglove.sdk.v1``, the one
the SDK's server accepts; the Foxglove app offers it): ``serverInfo`` and ``advertise``
come first, a ``subscribe`` gets binary ``messageData`` frames of the subscribed channels.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import Any

import foxglove

from drivers.clock import now_ns
from hilnav.bus import Bus
from hilnav.log.encoding import Encoder, Record, dumps, stamp_of
from hilnav.topics import log_topic

DEFAULT_PORT = 8765
DEFAULT_HOST = "127.0.0.1"
_ANY_OBJECT = {"type": "object"}


class LiveError(RuntimeError):
    """The live view cannot start (port taken, bad host): the message says why."""


class LiveBridge:
    """A Foxglove WebSocket server fed hilnav messages (see the module docstring).

    ``write(topic, msg, log_time_ns)`` encodes and serves one message;
    ``write_records`` serves records already encoded (the daemon encodes once for all its
    sinks). Thread-safe. ``port`` is the port it listens on (``port=0``: any free one)."""

    def __init__(
        self, port: int = DEFAULT_PORT, host: str = DEFAULT_HOST, name: str = "hilnav"
    ) -> None:
        self._ctx = foxglove.Context()
        try:
            self.server = foxglove.start_server(name=name, host=host, port=port, context=self._ctx)
        except Exception as exc:
            raise LiveError(
                f"cannot serve the live view on {host}:{port}: {exc} (another program may "
                "listen there: give another port)"
            ) from None
        self.host = host
        self.port: int = self.server.port
        self._encoder = Encoder()
        self._lock = threading.Lock()
        self._channels: dict[str, tuple[str, foxglove.Channel]] = {}
        self._closed = False
        self.messages = 0  # records handed to the server
        self.conflicts = 0  # records on a topic already served with another schema

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def write(
        self, topic: str, msg: Any, log_time_ns: int, publish_time_ns: int | None = None
    ) -> None:
        """Serve ``msg`` (a msgs dataclass) on ``topic`` and its Foxglove views."""
        self.write_records(self._encoder.encode(topic, msg), log_time_ns, publish_time_ns)

    def write_records(
        self, records: Sequence[Record], log_time_ns: int, publish_time_ns: int | None = None
    ) -> None:
        """Serve the records of one message (the protocol carries the log time only)."""
        with self._lock:
            if self._closed:
                return
            for r in records:
                channel = self._channel(r)
                if channel is not None:
                    channel.log(r.data, log_time=int(log_time_ns))
                    self.messages += 1

    def _channel(self, r: Record) -> foxglove.Channel | None:
        got = self._channels.get(r.topic)
        if got is None:
            schema = foxglove.Schema(
                name=r.schema_name, encoding="jsonschema", data=dumps(r.schema() or _ANY_OBJECT)
            )
            channel = foxglove.Channel(
                r.topic, schema=schema, message_encoding="json", context=self._ctx
            )
            got = self._channels[r.topic] = (r.schema_name, channel)
        if got[0] != r.schema_name:  # the protocol wants one channel per topic
            self.conflicts += 1
            return None
        return got[1]

    def close(self) -> None:
        """Stop the server (clients are disconnected). Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            channels = [c for _, c in self._channels.values()]
        for channel in channels:
            channel.close()
        self.server.stop()

    def __enter__(self) -> LiveBridge:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def serve_bus(bus: Bus, bridge: LiveBridge) -> Any:
    """Serve every valid hilnav message on the bus (``hilnav/*/**``, every robot) on the
    bridge: topic ``/<robot>/<topic>``, log time = when it arrived. Returns the
    subscriber (undeclared when the bus closes)."""

    def on_message(robot: str, topic: str, msg: Any) -> None:
        bridge.write(log_topic(robot, topic), msg, now_ns(), stamp_of(msg))

    return bus.subscribe_all(on_message)
