"""Read hilnav MCAP logs back into msgs dataclasses, also from truncated files.

:func:`read_messages` yields :class:`LoggedMessage` (topic, decoded msg, log and publish
times) in log-time order, decoding each record by its channel's schema name
(``hilnav.<Class>``, or ``foxglove.Grid`` for the map) with ``msgs.decode``. Foxglove views,
unknown schemas and malformed payloads are counted in :class:`ReadStats` and skipped.

A closed log is read through its summary (:func:`hilnav.log.indexed.iter_indexed`: the
chunks parsed by hand, merged in the mcap library's log-time order); a file without a
valid summary (a killed writer) is read record by record
(:func:`scan_records`): every complete record is used, the torn tail is ignored, a chunk
that does not decompress or fails its CRC is counted and skipped.
"""

from __future__ import annotations

import dataclasses
import importlib
import io
import os
import pkgutil
import struct
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from typing import Any, NamedTuple

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import (
    Attachment,
    Channel,
    Chunk,
    Footer,
    Header,
    Message,
    Metadata,
    Schema,
)
from mcap.stream_reader import breakup_chunk
from mcap.summary import Summary

import msgs
from hilnav.log.foxglove_schemas import SCHEMAS
from hilnav.log.indexed import iter_indexed
from hilnav.log.written_order import in_written_order

MAGIC = b"\x89MCAP0\r\n"
_HEAD = struct.Struct("<BQ")


@dataclass(frozen=True, slots=True)
class LoggedMessage:
    topic: str
    msg: Any
    log_time_ns: int
    publish_time_ns: int
    schema_name: str


@dataclass
class ReadStats:
    """What reading saw: decoded messages, and what it skipped and why."""

    messages: int = 0
    decoded: int = 0
    views: int = 0
    unknown: int = 0
    malformed: int = 0
    bad_chunks: int = 0
    truncated: bool = False
    set_backs: int = 0  # read as written: the times its log time went back (a clock set back)
    unknown_schemas: Counter = field(default_factory=Counter)
    errors: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["unknown_schemas"] = dict(sorted(self.unknown_schemas.items()))
        d["errors"] = self.errors[:10]
        return d


@cache
def message_types() -> dict[str, type]:
    """Schema name -> msgs dataclass, over every module of the msgs package."""
    out: dict[str, type] = {}
    for mod in pkgutil.iter_modules(msgs.__path__):
        try:
            m = importlib.import_module(f"msgs.{mod.name}")
        except ImportError:  # pragma: no cover - a broken optional module
            continue
        for obj in vars(m).values():
            if (
                isinstance(obj, type)
                and dataclasses.is_dataclass(obj)
                and obj.__module__ == m.__name__
            ):
                out.setdefault(msgs.schema_name(obj), obj)
    return out


def is_view(schema_name: str) -> bool:
    """A Foxglove view written beside a native message (not decoded back)."""
    return schema_name in SCHEMAS


# --------------------------------------------------------------------------------------
# Record-level scanning that survives a torn tail.


@dataclass
class ScanResult:
    """Bookkeeping of :func:`scan_records`."""

    file_size: int = 0
    valid_bytes: int = 0  # bytes up to the end of the last complete record
    complete: bool = False  # footer and closing magic present
    bad_chunks: int = 0
    errors: list[str] = field(default_factory=list)


def _parse(opcode: int, body: bytes) -> Any:
    s = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.HEADER:
        return Header.read(s)
    if opcode == Opcode.SCHEMA:
        return Schema.read(s)
    if opcode == Opcode.CHANNEL:
        return Channel.read(s)
    if opcode == Opcode.MESSAGE:
        return Message.read(s, len(body))
    if opcode == Opcode.CHUNK:
        return Chunk.read(s)
    if opcode == Opcode.METADATA:
        return Metadata.read(s)
    if opcode == Opcode.ATTACHMENT:
        return Attachment.read(s)
    if opcode == Opcode.FOOTER:
        return Footer.read(s)
    return None  # indexes, statistics, summary offsets, data end: rebuilt by writers


def scan_records(path: str | Path, result: ScanResult | None = None) -> Iterator[Any]:
    """Every complete Header/Schema/Channel/Message/Metadata/Attachment record in file order
    (chunks opened), stopping quietly at a torn tail. Fills ``result`` as it goes."""
    res = result if result is not None else ScanResult()
    with open(path, "rb") as f:
        size = os.fstat(f.fileno()).st_size
        res.file_size = size
        if f.read(8) != MAGIC:
            raise ValueError(f"{path}: not an MCAP file (bad magic)")
        pos = 8
        res.valid_bytes = pos
        while True:
            head = f.read(_HEAD.size)
            if len(head) < _HEAD.size:
                return
            opcode, length = _HEAD.unpack(head)
            if pos + _HEAD.size + length > size:
                return  # torn record
            body = f.read(length)
            pos += _HEAD.size + length
            try:
                rec = _parse(opcode, body)
            except (McapError, struct.error, ValueError, UnicodeDecodeError) as exc:
                res.errors.append(f"record at {pos - length - _HEAD.size}: {exc}")
                return  # garbage: nothing after it can be trusted
            res.valid_bytes = pos
            if isinstance(rec, Footer):
                res.complete = f.read(8) == MAGIC
                if res.complete:
                    res.valid_bytes += 8
                return
            if isinstance(rec, Chunk):
                try:
                    inner = breakup_chunk(rec, validate_crc=True)
                except Exception as exc:  # zstd/lz4 errors, CRC mismatch, torn inner record
                    res.bad_chunks += 1
                    res.errors.append(f"chunk at {pos - length - _HEAD.size}: {exc}")
                    continue
                yield from inner
            elif rec is not None:
                yield rec


# --------------------------------------------------------------------------------------
# Raw messages with their schema and channel, from a whole or a truncated file.


class RawRecord(NamedTuple):
    """One message record with its channel's topic and encoding and its schema."""

    topic: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes
    message_encoding: str
    log_time_ns: int
    publish_time_ns: int
    sequence: int
    data: bytes


def _raw_record(
    schema: Schema | None, channel: Channel, log_ns: int, pub_ns: int, seq: int, data: bytes
) -> RawRecord:
    return RawRecord(
        channel.topic,
        schema.name if schema else "",
        schema.encoding if schema else "",
        schema.data if schema else b"",
        channel.message_encoding,
        log_ns,
        pub_ns,
        seq,
        data,
    )


def _summary(path: str | Path) -> Summary | None:
    """The file's summary, if it ends with one that has statistics (a closed log)."""
    try:
        with open(path, "rb") as f:
            f.seek(-8, os.SEEK_END)
            if f.read(8) != MAGIC:
                return None
            f.seek(0)  # the reader checks the leading magic where the stream is
            summary = make_reader(f).get_summary()
            return summary if summary is not None and summary.statistics is not None else None
    except (OSError, McapError, struct.error, ValueError):
        return None


def _has_summary(path: str | Path) -> bool:
    return _summary(path) is not None


def iter_raw(
    path: str | Path,
    topics: Iterable[str] | None = None,
    stats: ReadStats | None = None,
    as_written: bool = False,
) -> Iterator[RawRecord]:
    """Every message record with its channel and schema, in log-time order when the file
    has a summary, else in file order (a truncated file). With ``as_written`` (replay and
    analysis): in file order, put in log-time order within each stretch of a log whose
    time went back (:mod:`hilnav.log.written_order`: the order things happened)."""
    wanted = set(topics) if topics is not None else None
    if as_written:
        yield from in_written_order(_in_file_order(path, wanted, stats), stats)
        return
    summary = _summary(path)
    if summary is not None and summary.chunk_indexes:
        with open(path, "rb") as f:
            for item in iter_indexed(f, summary, wanted):
                yield _raw_record(*item)
        return
    if summary is not None:
        with open(path, "rb") as f:
            reader = make_reader(f)
            for schema, channel, message in reader.iter_messages(
                topics=list(wanted) if wanted is not None else None, log_time_order=True
            ):
                yield _raw_record(
                    schema,
                    channel,
                    message.log_time,
                    message.publish_time,
                    message.sequence,
                    message.data,
                )
        return
    yield from _in_file_order(path, wanted, stats)


def _in_file_order(
    path: str | Path, wanted: set[str] | None, stats: ReadStats | None
) -> Iterator[RawRecord]:
    """The message records in the order they were written (every chunk read in turn)."""
    res = ScanResult()
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    for rec in scan_records(path, res):
        if isinstance(rec, Schema):
            schemas[rec.id] = rec
        elif isinstance(rec, Channel):
            channels[rec.id] = rec
        elif isinstance(rec, Message):
            ch = channels.get(rec.channel_id)
            if ch is None:
                if stats is not None:
                    stats.unknown += 1
                continue
            if wanted is not None and ch.topic not in wanted:
                continue
            sc = schemas.get(ch.schema_id)
            yield _raw_record(sc, ch, rec.log_time, rec.publish_time, rec.sequence, rec.data)
    if stats is not None:
        stats.truncated = not res.complete
        stats.bad_chunks += res.bad_chunks
        stats.errors.extend(res.errors)


def topic_counts(path: str | Path) -> Counter[str]:
    """Messages per topic: from the summary's statistics, else by reading every record."""
    summary = _summary(path)
    counts: Counter[str] = Counter()
    if summary is not None and summary.statistics is not None:
        for cid, n in summary.statistics.channel_message_counts.items():
            channel = summary.channels.get(cid)
            if channel is not None and n:
                counts[channel.topic] += n
        return counts
    for r in iter_raw(path):
        counts[r.topic] += 1
    return counts


def decode_record(
    r: RawRecord, stats: ReadStats, types: dict[str, type] | None = None
) -> LoggedMessage | None:
    """Decode one raw record to its msgs dataclass, or count why not and return None."""
    types = types if types is not None else message_types()
    stats.messages += 1
    if is_view(r.schema_name):
        stats.views += 1
        return None
    cls = types.get(r.schema_name)
    if cls is None or r.message_encoding != "json":
        stats.unknown += 1
        stats.unknown_schemas[r.schema_name or "(none)"] += 1
        return None
    try:
        msg = msgs.decode(cls, r.data)
    except (msgs.DecodeError, TypeError, ValueError) as exc:
        stats.malformed += 1
        if len(stats.errors) < 100:
            stats.errors.append(f"{r.topic} @ {r.log_time_ns}: {exc}")
        return None
    stats.decoded += 1
    return LoggedMessage(r.topic, msg, r.log_time_ns, r.publish_time_ns, r.schema_name)


def read_messages(
    path: str | Path, topics: Iterable[str] | None = None, stats: ReadStats | None = None
) -> Iterator[LoggedMessage]:
    """Decoded messages of a log; views, unknown schemas and malformed payloads skipped
    (and counted in ``stats``)."""
    st = stats if stats is not None else ReadStats()
    types = message_types()
    for r in iter_raw(path, topics, st):
        m = decode_record(r, st, types)
        if m is not None:
            yield m


def read_metadata(path: str | Path) -> dict[str, dict[str, str]]:
    """The MCAP metadata records by name (the writer's "hilnav" record: robot, plan ...)."""
    out: dict[str, dict[str, str]] = {}
    if _has_summary(path):
        with open(path, "rb") as f:
            for m in make_reader(f).iter_metadata():
                out[m.name] = dict(m.metadata)
        return out
    for rec in scan_records(path):
        if isinstance(rec, Metadata):
            out[rec.name] = dict(rec.metadata)
    return out
