"""What one message becomes on the log's channels, and the sinks that take it.

:class:`Encoder` turns ``(topic, msg)`` into :class:`Record` items: first the native
record (topic ``/<robot>/<topic>``, schema ``hilnav.<Class>`` whose JSON Schema is
``msgs.json_schema``, or Foxglove's official one for a message that is a Foxglove message
such as the map's ``foxglove.Grid``; payload ``msgs.encode``), then the Foxglove views of
:func:`hilnav.log.foxglove.views` (JSON, schemas from :mod:`hilnav.log.foxglove_schemas`).
The MCAP writer (:class:`hilnav.log.writer.LogWriter`) and the live Foxglove bridge
(:class:`hilnav.live.LiveBridge`) both write these records, so a live client and a log
file see the same channels, schemas and bytes.

A :class:`Sink` takes the records of one message with its log and publish times; the
daemon encodes each message once and hands the records to each of its sinks. Encoders of
several robots in one process (a fleet host: every robot logs every peer's box) may share
a :class:`ViewMemo`: the views of a message logged on the same topic with the same native
bytes are made once.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Sequence
from typing import Any, NamedTuple, Protocol

import msgspec

import msgs
from hilnav.log import foxglove
from hilnav.log.foxglove_schemas import SCHEMAS, official_schema

_ENCODE = msgspec.json.Encoder().encode


def dumps(obj: Any) -> bytes:
    """Compact JSON bytes; ValueError on NaN or infinity (JSON cannot hold them).

    msgspec writes NaN and infinity as null: a payload with a null is made again by
    ``json``, which refuses them (and writes a real None as null too)."""
    try:
        data = _ENCODE(obj)
    except (TypeError, OverflowError):
        data = b"null"
    if b"null" in data:
        return json.dumps(obj, separators=(",", ":"), allow_nan=False).encode("utf-8")
    return data


def stamp_of(msg: Any) -> int | None:
    """The message's ``stamp_ns`` as a publish time, or None when it has none (or one that
    is not a positive int64)."""
    stamp = getattr(msg, "stamp_ns", None)
    return stamp if isinstance(stamp, int) and 0 < stamp < 2**63 else None


class Record(NamedTuple):
    """One encoded payload on one channel (JSON message encoding).

    ``cls`` is the msgs class of a native record, None for a Foxglove view. (A named
    tuple: made for every message, it costs a third of a frozen dataclass.)"""

    topic: str
    schema_name: str
    data: bytes
    cls: type | None = None

    def schema(self) -> dict[str, Any] | None:
        """The JSON Schema of the channel (None: a view schema hilnav has no schema for)."""
        if self.cls is not None:  # a hilnav message; the map is a foxglove.Grid itself
            return official_schema(self.schema_name) or msgs.json_schema(self.cls)
        return SCHEMAS.get(self.schema_name)

    @property
    def is_view(self) -> bool:
        return self.cls is None


_SCHEMA_NAMES: dict[type, str] = {}


class ViewMemo:
    """What the encoders of one process share for messages of ``classes``: a message's
    records when it is the very message last encoded on its topic (a fleet host hands
    one decoded peer box to each of its robots), else its Foxglove views by (log topic,
    native record bytes). Only for classes whose views are a function of the topic and
    the message alone (:func:`hilnav.log.foxglove.views_use_state` false; ValueError
    otherwise; messages are frozen): equal bytes, equal message, equal views. At most
    ``size`` views (then it starts again empty)."""

    def __init__(self, classes: Sequence[type], size: int = 4096) -> None:
        stateful = [c.__name__ for c in classes if foxglove.views_use_state(c)]
        if stateful:
            raise ValueError(f"views of {', '.join(stateful)} depend on earlier messages")
        self.classes = frozenset(classes)
        self.size = size
        self.hits = 0  # messages whose records or views were found here
        self._views: dict[tuple[str, bytes], list[Record]] = {}
        self._last: dict[str, tuple[Any, tuple[Record, ...]]] = {}  # topic -> (msg, records)

    def last(self, topic: str, msg: Any) -> tuple[Record, ...] | None:
        """The records of ``msg`` if it is the message last encoded on ``topic``."""
        last = self._last.get(topic)
        if last is not None and last[0] is msg:
            self.hits += 1
            return last[1]
        return None

    def views(self, topic: str, data: bytes) -> list[Record] | None:
        views = self._views.get((topic, data))
        if views is not None:
            self.hits += 1
        return views

    def keep(self, topic: str, msg: Any, records: list[Record]) -> None:
        """``msg``'s records (the native one first) as encoded on ``topic``."""
        if len(self._views) >= self.size:
            self._views.clear()
        self._views[(topic, records[0].data)] = records[1:]
        self._last[topic] = (msg, tuple(records))


def _schema_name(cls: type) -> str:
    """``msgs.schema_name(cls)``, looked up once per class."""
    name = _SCHEMA_NAMES.get(cls)
    if name is None:
        name = _SCHEMA_NAMES[cls] = msgs.schema_name(cls)
    return name


class Encoder:
    """``encode(topic, msg)``: the native record and its Foxglove views (thread-safe).

    Keeps the views' state (the latest odometry pose, for map->odom), so one encoder
    should see one stream of messages in order. A view that cannot be made (an odd
    message, NaN in a diverged filter) is counted in ``views_skipped`` and left out; the
    native record is what matters. An unencodable native message raises."""

    def __init__(self, views: bool = True, memo: ViewMemo | None = None) -> None:
        self.views = views
        self.views_skipped = 0
        self.memo = memo  # views shared with other encoders (module docstring)
        self._state = foxglove.ViewState()
        self._lock = threading.Lock()

    def encode(self, topic: str, msg: Any, native: bytes | None = None) -> list[Record]:
        """The native record, then the views. ``native``: the bytes ``msg`` was decoded
        from (its record in a log being replayed), used instead of encoding it again."""
        cls = type(msg)
        name = _schema_name(cls)
        memo = self.memo
        if memo is not None and self.views and cls in memo.classes:
            return self._shared(memo, topic, name, msg)
        data = msgs.encode(msg) if native is None else bytes(native)
        return [Record(topic, name, data, cls), *self.views_of(topic, msg)]

    @property
    def splits(self) -> bool:
        """Whether :meth:`native` then :meth:`views_of` give what :meth:`encode` gives
        (not through a memo of views shared with other encoders)."""
        return self.memo is None

    def native(self, topic: str, msg: Any) -> Record:
        """The native record alone (its views later, in the messages' order, by
        :meth:`views_of`): what a put needs at once."""
        cls = type(msg)
        return Record(topic, _schema_name(cls), msgs.encode(msg), cls)

    def views_of(self, topic: str, msg: Any) -> list[Record]:
        """The Foxglove views :meth:`encode` would add to the native record."""
        if self.views and foxglove.may_have_views(type(msg)):
            with self._lock:
                return self._views(topic, msg)
        return []

    def _shared(self, memo: ViewMemo, topic: str, name: str, msg: Any) -> list[Record]:
        """:meth:`encode` through the memo (records and views made once per process)."""
        known = memo.last(topic, msg)
        if known is not None:
            return list(known)
        data = msgs.encode(msg)
        out = [Record(topic, name, data, type(msg))]
        if foxglove.may_have_views(type(msg)):
            views = memo.views(topic, data)
            if views is None:
                with self._lock:
                    views = self._views(topic, msg)
            out.extend(views)
        memo.keep(topic, msg, out)
        return out

    def _views(self, topic: str, msg: Any) -> list[Record]:
        try:
            views = foxglove.views(topic, msg, self._state)
        except (TypeError, ValueError, AttributeError):
            self.views_skipped += 1
            return []
        out = []
        for vtopic, vschema, body in views:
            try:
                out.append(Record(vtopic, vschema, dumps(body)))
            except ValueError:  # NaN/inf: Foxglove JSON cannot hold it
                self.views_skipped += 1
        return out


class Sink(Protocol):
    """Where encoded records go: the MCAP log, the live Foxglove bridge."""

    def write_records(
        self, records: Sequence[Record], log_time_ns: int, publish_time_ns: int | None = None
    ) -> None: ...

    def close(self) -> None: ...
