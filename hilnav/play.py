"""``hilnav play``: a log's messages back onto the Zenoh bus, in real time, as if live.

Like ``ros2 bag play``: the records of a log (whole or truncated, read in log-time order
by :func:`hilnav.log.reader.iter_raw`) are put on ``hilnav/<robot>/<topic>`` (from the
MCAP topic ``/<robot>/<topic>``), paced by their log times divided by ``rate``, with the
sender named as the robot the topic belongs to, so the daemons of a fleet, ``hilnav
view`` and any other subscriber take them for that robot's own.

Stamps are shifted to now: at the start of each pass, ``offset = now - first log time``,
and every stamp of a payload, each ``*_ns`` integer field (zero means "never" and stays)
and each Foxglove time ``{"sec", "nsec"}``, is moved by that same offset. The payload is
the log's JSON otherwise untouched. The stamps keep the log's spacing, so at a ``rate``
other than 1 they run ahead of (or behind) the wall clock; with ``loop`` a pass starts
its stamps after the previous pass's last, so they never go back.

By default only the native messages are played: the Foxglove views and the raw device
bytes are left out unless ``topics`` names them (exact MCAP topics or ``fnmatch``
patterns such as ``/r1/*``). A topic without a robot part (``/tf``) cannot be played.
Playing ends at the end of the log, or with ``loop`` when ``stop`` is set.
"""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from drivers.clock import now_ns
from hilnav.bus import Bus, check_name
from hilnav.log.cat import wanted
from hilnav.log.reader import RawRecord, ReadStats, is_view, iter_raw, message_types
from hilnav.topics import RAW_PREFIX, split_log_topic
from msgs import RawBytes, schema_name

_RAW_SCHEMA = schema_name(RawBytes)


def shift_stamps(obj: Any, offset_ns: int) -> Any:
    """``obj`` (parsed JSON) with every positive ``*_ns`` integer and every ``{"sec",
    "nsec"}`` time moved by ``offset_ns`` (times never go below zero)."""
    if isinstance(obj, dict):
        if set(obj) == {"sec", "nsec"} and all(type(v) is int for v in obj.values()):
            t = max(0, obj["sec"] * 1_000_000_000 + obj["nsec"] + offset_ns)
            return {"sec": t // 1_000_000_000, "nsec": t % 1_000_000_000}
        out = {}
        for k, v in obj.items():
            if k.endswith("_ns") and type(v) is int and v > 0:
                out[k] = max(0, v + offset_ns)
            else:
                out[k] = shift_stamps(v, offset_ns)
        return out
    if isinstance(obj, list):
        return [shift_stamps(v, offset_ns) for v in obj]
    return obj


def shifted_payload(data: bytes, offset_ns: int) -> bytes:
    """A JSON payload with its stamps shifted (:func:`shift_stamps`), compact as logged."""
    obj = shift_stamps(json.loads(data), offset_ns)
    return json.dumps(obj, separators=(",", ":"), allow_nan=False).encode("utf-8")


def _key_chunk(robot: str) -> bool:
    try:
        check_name(robot)
    except ValueError:
        return False
    return True


class Selection:
    """Which records are played: the native messages by default, or what ``topics`` names."""

    def __init__(self, topics: Iterable[str] | None = None) -> None:
        self.patterns = tuple(topics) if topics else ()
        self._types = message_types()

    def __call__(self, r: RawRecord) -> bool:
        robot, name = split_log_topic(r.topic)
        if r.message_encoding != "json" or not robot or not _key_chunk(robot):
            return False
        if self.patterns:
            return wanted(r.topic, self.patterns)
        native = r.schema_name in self._types and not is_view(r.schema_name)
        return native and r.schema_name != _RAW_SCHEMA and not name.startswith(RAW_PREFIX)


@dataclass
class PlayReport:
    """What a play did: messages put on the bus (per MCAP topic) and passes made."""

    published: int = 0
    passes: int = 0
    per_topic: dict[str, int] = field(default_factory=dict)
    skipped: int = 0  # selected records whose payload is not JSON
    stopped: bool = False  # by stop, before the end

    def as_dict(self) -> dict[str, Any]:
        return {
            "published": self.published,
            "passes": self.passes,
            "skipped": self.skipped,
            "stopped": self.stopped,
            "per_topic": dict(sorted(self.per_topic.items())),
        }


class Player:
    """Puts a log's records on a bus in real time (see the module docstring)."""

    def __init__(
        self,
        path: str | Path,
        bus: Bus,
        *,
        rate: float = 1.0,
        topics: Iterable[str] | None = None,
        stop: threading.Event | None = None,
    ) -> None:
        if not rate > 0:
            raise ValueError(f"rate {rate}: must be > 0")
        self.path = Path(path)
        self.bus = bus
        self.rate = float(rate)
        self.select = Selection(topics)
        self.stop = stop if stop is not None else threading.Event()
        self.report = PlayReport()
        self._min_offset = -(2**63)  # the next pass's stamps come after this pass's

    def play(self, loop: bool = False) -> PlayReport:
        """One pass over the log, or passes until ``stop`` with ``loop``."""
        while not self.stop.is_set():
            n = self.one_pass()
            self.report.passes += 1
            if not loop or n == 0:
                break
        self.report.stopped = self.stop.is_set()
        return self.report

    def one_pass(self) -> int:
        """Play the log once; the number of messages put on the bus."""
        first: int | None = None
        wall0 = offset = last = 0
        n = 0
        for r in iter_raw(self.path, stats=ReadStats()):
            if not self.select(r):
                continue
            if first is None:
                first, wall0 = r.log_time_ns, time.monotonic()
                offset = max(now_ns() - first, self._min_offset)
            delay = wall0 + (r.log_time_ns - first) / 1e9 / self.rate - time.monotonic()
            if self.stop.wait(delay) if delay > 0 else self.stop.is_set():
                return n
            self._put(r, offset)
            n += 1
            last = max(last, r.log_time_ns)
        if first is not None:
            self._min_offset = offset + (last - first) + 1
        return n

    def _put(self, r: RawRecord, offset_ns: int) -> None:
        robot, name = split_log_topic(r.topic)
        try:
            data = shifted_payload(r.data, offset_ns)
        except ValueError:  # not JSON after all
            self.report.skipped += 1
            return
        self.bus.put_encoded(robot, name, data, r.schema_name, sender=robot)
        self.report.published += 1
        self.report.per_topic[r.topic] = self.report.per_topic.get(r.topic, 0) + 1
