"""``hilnav log recover IN OUT``: rewrite a truncated MCAP log into a valid one.

A writer killed mid-run leaves a file without its summary and footer, possibly with a torn
last record. Every complete record is read (:func:`hilnav.log.reader.scan_records`) and
written again, with the same schemas, channels, log/publish times, sequence numbers,
metadata and attachments, into a new file with a proper summary. The report says what
was kept and what was lost (the torn tail's bytes, chunks that failed their CRC).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mcap.records import Attachment, Channel, Header, Message, Metadata, Schema
from mcap.writer import CompressionType, Writer

from hilnav.log.reader import ScanResult, scan_records


@dataclass
class RecoverReport:
    input: str
    output: str
    input_bytes: int = 0
    valid_bytes: int = 0
    input_complete: bool = False
    messages: int = 0
    orphan_messages: int = 0  # messages whose channel record was lost
    schemas: int = 0
    channels: int = 0
    metadata: int = 0
    attachments: int = 0
    bad_chunks: int = 0
    first_ns: int = 0
    last_ns: int = 0
    per_topic: Counter = field(default_factory=Counter)
    errors: list[str] = field(default_factory=list)

    @property
    def lost_bytes(self) -> int:
        return self.input_bytes - self.valid_bytes

    def as_dict(self) -> dict[str, Any]:
        return {
            "input": self.input,
            "output": self.output,
            "input_bytes": self.input_bytes,
            "input_complete": self.input_complete,
            "valid_bytes": self.valid_bytes,
            "lost_tail_bytes": self.lost_bytes,
            "messages": self.messages,
            "orphan_messages": self.orphan_messages,
            "schemas": self.schemas,
            "channels": self.channels,
            "metadata": self.metadata,
            "attachments": self.attachments,
            "bad_chunks": self.bad_chunks,
            "first_ns": self.first_ns,
            "last_ns": self.last_ns,
            "duration_s": round((self.last_ns - self.first_ns) / 1e9, 6) if self.messages else 0.0,
            "per_topic": dict(sorted(self.per_topic.items())),
            "errors": self.errors[:10],
        }


# The mcap library's writer (it also copies attachments, which hilnav's own never writes).
_COMPRESSIONS = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}


def recover(src: str | Path, dst: str | Path, compression: str = "zstd") -> RecoverReport:
    """Copy every complete record of ``src`` into a valid MCAP ``dst``."""
    src, dst = Path(src), Path(dst)
    if src.resolve() == dst.resolve():
        raise ValueError("recover writes a new file: OUT must differ from IN")
    rep = RecoverReport(str(src), str(dst))
    scan = ScanResult()
    schema_map: dict[int, int] = {}
    channel_map: dict[int, int] = {}
    channel_topic: dict[int, str] = {}
    pending_channels: dict[int, Channel] = {}
    with open(dst, "wb") as out:
        w = Writer(out, compression=_COMPRESSIONS.get(compression, CompressionType.ZSTD))
        started = False
        for rec in scan_records(src, scan):
            if isinstance(rec, Header):
                if not started:
                    w.start(profile=rec.profile, library=rec.library or "hilnav")
                    started = True
                continue
            if not started:
                w.start(library="hilnav")
                started = True
            if isinstance(rec, Schema):
                if rec.id not in schema_map:
                    schema_map[rec.id] = w.register_schema(rec.name, rec.encoding, rec.data)
                    rep.schemas += 1
            elif isinstance(rec, Channel):
                if rec.id in channel_map:
                    continue
                if rec.schema_id != 0 and rec.schema_id not in schema_map:
                    pending_channels[rec.id] = rec  # schema record lost: keep schema-less
                sid = schema_map.get(rec.schema_id, 0)
                channel_map[rec.id] = w.register_channel(
                    rec.topic, rec.message_encoding, sid, dict(rec.metadata)
                )
                channel_topic[rec.id] = rec.topic
                rep.channels += 1
            elif isinstance(rec, Message):
                cid = channel_map.get(rec.channel_id)
                if cid is None:
                    rep.orphan_messages += 1
                    continue
                w.add_message(cid, rec.log_time, rec.data, rec.publish_time, rec.sequence)
                if rep.messages == 0:
                    rep.first_ns = rep.last_ns = rec.log_time
                rep.messages += 1
                rep.first_ns = min(rep.first_ns, rec.log_time)
                rep.last_ns = max(rep.last_ns, rec.log_time)
                rep.per_topic[channel_topic[rec.channel_id]] += 1
            elif isinstance(rec, Metadata):
                w.add_metadata(rec.name, dict(rec.metadata))
                rep.metadata += 1
            elif isinstance(rec, Attachment):
                w.add_attachment(rec.create_time, rec.log_time, rec.name, rec.media_type, rec.data)
                rep.attachments += 1
        if not started:
            w.start(library="hilnav")
        w.finish()
    rep.input_bytes = scan.file_size
    rep.valid_bytes = scan.valid_bytes
    rep.input_complete = scan.complete
    rep.bad_chunks = scan.bad_chunks
    rep.errors = list(scan.errors)
    if pending_channels:
        rep.errors.append(f"{len(pending_channels)} channel(s) lost their schema record")
    return rep
