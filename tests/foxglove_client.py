"""A minimal Foxglove WebSocket protocol client for the tests (the ``websockets`` package).

It offers the subprotocols ``foxglove.sdk.v1`` (what foxglove-sdk's server accepts) and
``foxglove.websocket.v1`` (the older name of the same protocol), reads ``serverInfo`` and
``advertise``, subscribes to the channels whose topic it wants as they are advertised,
and decodes the binary ``messageData`` frames: opcode 1, subscription id (u32), log time
(u64), payload.

foxglove-sdk 0.30's server may advertise a channel created while a client is connecting
and then answer its subscription with the status "Unknown channel ID" (the channel stays
dark for that client). A user reconnects; so does this client, keeping what it received.
"""

from __future__ import annotations

import json
import struct
import time
from dataclasses import dataclass, field
from typing import Any

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect
from websockets.typing import Subprotocol

SUBPROTOCOLS = [Subprotocol("foxglove.sdk.v1"), Subprotocol("foxglove.websocket.v1")]
MESSAGE_DATA = 0x01


@dataclass
class Received:
    topic: str
    schema_name: str
    log_time_ns: int
    data: bytes

    def json(self) -> Any:
        return json.loads(self.data)


@dataclass
class FoxgloveClient:
    """Connect (retrying until ``timeout_s``), then :meth:`collect` messages."""

    url: str
    timeout_s: float = 60.0
    ws: ClientConnection | None = None
    server_info: dict[str, Any] = field(default_factory=dict)
    channels: dict[int, dict[str, Any]] = field(default_factory=dict)  # id -> advertised
    subscriptions: dict[int, int] = field(default_factory=dict)  # sub id -> channel id
    received: list[Received] = field(default_factory=list)

    reconnects: int = 0

    def __enter__(self) -> FoxgloveClient:
        self._connect()
        return self

    def _connect(self) -> None:
        end = time.monotonic() + self.timeout_s
        while True:
            try:
                ws = connect(self.url, subprotocols=SUBPROTOCOLS, open_timeout=5)
                self.ws = ws.__enter__()  # the context manager's entry: no legacy warning
                break
            except OSError:  # the server is not up yet
                if time.monotonic() > end:
                    raise
                time.sleep(0.2)

    def _reconnect(self) -> None:
        assert self.ws is not None and self.reconnects < 5, "too many reconnections"
        self.ws.close()
        self.reconnects += 1
        self.channels.clear()
        self.subscriptions.clear()
        self._connect()

    def __exit__(self, *exc: object) -> None:
        if self.ws is not None:
            self.ws.close()

    def _subscribe(self, ids: list[int]) -> None:
        subs = []
        for cid in ids:
            sid = len(self.subscriptions) + 1
            self.subscriptions[sid] = cid
            subs.append({"id": sid, "channelId": cid})
        if subs:
            assert self.ws is not None
            self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    def _handle(self, frame: str | bytes, wanted: Any) -> None:
        if isinstance(frame, bytes):
            assert frame[0] == MESSAGE_DATA, frame[:1]
            sid, log_ns = struct.unpack_from("<IQ", frame, 1)
            ch = self.channels[self.subscriptions[sid]]
            self.received.append(Received(ch["topic"], ch["schemaName"], log_ns, frame[13:]))
            return
        msg = json.loads(frame)
        if msg["op"] == "status" and "Unknown channel" in msg.get("message", ""):
            self._reconnect()
        elif msg["op"] == "serverInfo":
            self.server_info = msg
        elif msg["op"] == "advertise":
            new = [c for c in msg["channels"] if c["id"] not in self.channels]
            self.channels.update({c["id"]: c for c in new})
            self._subscribe([c["id"] for c in new if wanted(c["topic"])])

    def collect(self, wanted: Any, done: Any, step: Any = None) -> list[Received]:
        """Subscribe to every advertised channel whose topic ``wanted(topic)`` accepts and
        receive until ``done(received)``; ``step()`` runs between frames, at most ten
        times a second (to feed the server). AssertionError after ``timeout_s``."""
        assert self.ws is not None
        end = time.monotonic() + self.timeout_s
        next_step = 0.0
        while not done(self.received):
            now = time.monotonic()
            assert now < end, (
                f"gave up: channels {sorted(c['topic'] for c in self.channels.values())}, "
                f"{len(self.received)} messages"
            )
            if step is not None and now >= next_step:  # at most 10 times a second
                step()
                next_step = now + 0.1
            try:
                frame = self.ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            except ConnectionClosed as exc:
                raise AssertionError(f"server closed the connection: {exc}") from None
            self._handle(frame, wanted)
        return self.received
