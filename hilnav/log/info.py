"""``hilnav log info``: what a log holds — topics, schemas, counts, rates, duration."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hilnav.log.reader import ReadStats, iter_raw, read_metadata


@dataclass
class TopicInfo:
    topic: str
    schema: str
    encoding: str
    count: int = 0
    bytes: int = 0
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


def log_info(path: str | Path) -> LogInfo:
    """Scan a log (whole or truncated) and count what is in it."""
    p = Path(path)
    stats = ReadStats()
    topics: dict[tuple[str, str], TopicInfo] = {}
    for r in iter_raw(p, stats=stats):
        key = (r.topic, r.schema_name)
        t = topics.get(key)
        if t is None:
            t = topics[key] = TopicInfo(r.topic, r.schema_name, r.message_encoding)
            t.first_ns = t.last_ns = r.log_time_ns
        t.count += 1
        t.bytes += len(r.data)
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
