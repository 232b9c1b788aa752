"""``hilnav log info``: what a log holds — topics, schemas, counts, rates, duration.

A finished file is answered from its MCAP summary section: the statistics record gives
the count per channel, and each channel's first and last log time come from the message
index records of the chunks at its two ends (the chunk indexes tell which chunks hold it
and their time spans), so the answer costs a few small reads whatever the file's size
and no chunk is decompressed. Payload sizes are not in the summary: ``bytes`` per topic is
None there. A file without a usable summary (a killed writer, no message indexes), or
``scan=True``, is read record by record (:func:`hilnav.log.reader.iter_raw`): same
figures, plus the payload bytes and the count of bad chunks.
"""

from __future__ import annotations

import io
import os
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import ChunkIndex, MessageIndex

from hilnav.log.reader import MAGIC, ReadStats, iter_raw, read_metadata


@dataclass
class TopicInfo:
    topic: str
    schema: str
    encoding: str
    count: int = 0
    bytes: int | None = 0  # None: answered from the summary, which has no sizes
    first_ns: int = 0
    last_ns: int = 0

    @property
    def rate_hz(self) -> float:
        span = (self.last_ns - self.first_ns) / 1e9
        return (self.count - 1) / span if self.count > 1 and span > 0 else 0.0


@dataclass
class LogInfo:
    path: str
    file_bytes: int
    complete: bool
    topics: dict[tuple[str, str], TopicInfo] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    bad_chunks: int = 0
    source: str = "scan"  # "summary" or "scan": how the figures were found

    @property
    def messages(self) -> int:
        return sum(t.count for t in self.topics.values())

    @property
    def start_ns(self) -> int:
        return min((t.first_ns for t in self.topics.values()), default=0)

    @property
    def end_ns(self) -> int:
        return max((t.last_ns for t in self.topics.values()), default=0)

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) / 1e9

    def as_dict(self) -> dict[str, Any]:
        return {
            "path": self.path,
            "file_bytes": self.file_bytes,
            "complete": self.complete,
            "messages": self.messages,
            "start_ns": self.start_ns,
            "end_ns": self.end_ns,
            "duration_s": round(self.duration_s, 6),
            "bad_chunks": self.bad_chunks,
            "source": self.source,
            "metadata": self.metadata,
            "topics": [
                {
                    "topic": t.topic,
                    "schema": t.schema,
                    "encoding": t.encoding,
                    "count": t.count,
                    "bytes": t.bytes,
                    "first_ns": t.first_ns,
                    "last_ns": t.last_ns,
                    "rate_hz": round(t.rate_hz, 3),
                }
                for t in sorted(self.topics.values(), key=lambda t: (t.topic, t.schema))
            ],
        }

    def table(self) -> str:
        lines = [
            f"file:      {self.path} ({self.file_bytes} bytes)"
            + ("" if self.complete else "  TRUNCATED: run `hilnav log recover`"),
            f"messages:  {self.messages}",
            f"duration:  {self.duration_s:.3f} s",
        ]
        for name, md in sorted(self.metadata.items()):
            lines.append(
                f"metadata {name}: " + ", ".join(f"{k}={v}" for k, v in sorted(md.items()))
            )
        if self.bad_chunks:
            lines.append(f"bad chunks skipped: {self.bad_chunks}")
        rows = sorted(self.topics.values(), key=lambda t: (t.topic, t.schema))
        w_topic = max([len("topic")] + [len(t.topic) for t in rows])
        w_schema = max([len("schema")] + [len(t.schema) for t in rows])
        lines.append("")
        lines.append(f"{'topic':<{w_topic}}  {'schema':<{w_schema}}  {'count':>8}  {'rate Hz':>9}")
        for t in rows:
            lines.append(
                f"{t.topic:<{w_topic}}  {t.schema:<{w_schema}}  {t.count:>8}  {t.rate_hz:>9.2f}"
            )
        return "\n".join(lines)


def log_info(path: str | Path, scan: bool = False) -> LogInfo:
    """What a log holds: from its summary when it has one (unless ``scan``), else by
    reading every record (a truncated file too)."""
    p = Path(path)
    if not scan:
        info = _from_summary(p)
        if info is not None:
            return info
    return _scan(p)


def _scan(p: Path) -> LogInfo:
    stats = ReadStats()
    topics: dict[tuple[str, str], TopicInfo] = {}
    for r in iter_raw(p, stats=stats):
        key = (r.topic, r.schema_name)
        t = topics.get(key)
        if t is None:
            t = topics[key] = TopicInfo(r.topic, r.schema_name, r.message_encoding)
            t.first_ns = t.last_ns = r.log_time_ns
        t.count += 1
        t.bytes = (t.bytes or 0) + len(r.data)
        t.first_ns = min(t.first_ns, r.log_time_ns)
        t.last_ns = max(t.last_ns, r.log_time_ns)
    return LogInfo(
        path=str(p),
        file_bytes=p.stat().st_size,
        complete=not stats.truncated,
        topics=topics,
        metadata=read_metadata(p),
        bad_chunks=stats.bad_chunks,
    )


def _from_summary(p: Path) -> LogInfo | None:
    """The figures from the summary section, or None when the file has no usable one."""
    try:
        with open(p, "rb") as f:
            f.seek(-len(MAGIC), os.SEEK_END)
            if f.read(len(MAGIC)) != MAGIC:
                return None
            f.seek(0)
            summary = make_reader(f).get_summary()
            if summary is None or summary.statistics is None:
                return None
            topics: dict[tuple[str, str], TopicInfo] = {}
            for cid, n in summary.statistics.channel_message_counts.items():
                ch = summary.channels.get(cid)
                span = _channel_span(f, summary.chunk_indexes, cid) if n else None
                if ch is None or span is None:
                    if n:
                        return None  # no channel record or no message index: scan it
                    continue
                sc = summary.schemas.get(ch.schema_id)
                key = (ch.topic, sc.name if sc else "")
                t = topics.get(key)
                if t is None:
                    t = topics[key] = TopicInfo(*key, ch.message_encoding, 0, None, *span)
                t.count += n
                t.first_ns, t.last_ns = min(t.first_ns, span[0]), max(t.last_ns, span[1])
    except (OSError, McapError, struct.error, ValueError, EOFError):
        return None
    return LogInfo(str(p), p.stat().st_size, True, topics, read_metadata(p), source="summary")


def _channel_span(f: BinaryIO, chunks: list[ChunkIndex], cid: int) -> tuple[int, int] | None:
    """A channel's first and last log time, from the message indexes of the fewest chunks:
    chunks are visited by start (end) time until none can hold an earlier (later) one."""
    holding = [c for c in chunks if cid in c.message_index_offsets]
    if not holding:
        return None
    first = last = None
    for c in sorted(holding, key=lambda c: c.message_start_time):
        if first is not None and c.message_start_time >= first:
            break
        times = _index_times(f, c.message_index_offsets[cid])
        first = min(times) if first is None else min(first, *times)
    for c in sorted(holding, key=lambda c: -c.message_end_time):
        if last is not None and c.message_end_time <= last:
            break
        times = _index_times(f, c.message_index_offsets[cid])
        last = max(times) if last is None else max(last, *times)
    return (first, last) if first is not None and last is not None else None


def _index_times(f: BinaryIO, offset: int) -> list[int]:
    """The log times of one MessageIndex record (at ``offset`` in the file)."""
    f.seek(offset)
    opcode, length = struct.unpack("<BQ", f.read(9))
    if opcode != Opcode.MESSAGE_INDEX:
        raise ValueError(f"no message index at {offset}")
    index = MessageIndex.read(ReadDataStream(io.BytesIO(f.read(length))))
    times = [t for t, _ in index.records]
    if not times:
        raise ValueError(f"empty message index at {offset}")
    return times
