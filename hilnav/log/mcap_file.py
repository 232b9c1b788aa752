"""An MCAP file written chunk by chunk, with the messages packed by hand.

The mcap library's ``Writer`` builds a ``Message`` object per message, writes its fields
one ``struct.pack`` at a time into a ``BytesIO`` (seeking back for the length) and keeps
its indexes in record objects: about 4 us per message, most of the log writer's time.
:class:`McapFile` writes the same file: the same records in the same order (header;
schemas and channels inside the open chunk; chunks, each followed by its message
indexes; metadata outside the chunks; data end; the summary with schemas, channels,
statistics, chunk indexes, attachment and metadata indexes, summary offsets; the footer
with the summary CRC), so its bytes equal those of ``mcap.writer.Writer`` given the same
calls (tests/test_log_mcap_file.py checks that). Everything but a message is written with
mcap's own record classes (``mcap.records``); a message is one ``struct.pack`` of its
header appended to the open chunk's ``bytearray``, and its index entry two list appends.
Chunks are compressed with one reused zstd (level 3, as the library) or lz4 compressor.

Not thread-safe: :class:`hilnav.log.writer.LogWriter` holds its lock around every call.
"""

from __future__ import annotations

import struct
import zlib
from typing import BinaryIO

import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import (
    Channel,
    Chunk,
    ChunkIndex,
    DataEnd,
    Footer,
    Header,
    Metadata,
    MetadataIndex,
    Schema,
    Statistics,
    SummaryOffset,
)

MAGIC = b"\x89MCAP0\r\n"
COMPRESSIONS = ("zstd", "lz4", "none")
_MESSAGE = struct.Struct("<BQHIQQ")  # opcode, record length, channel, sequence, log, publish
_MESSAGE_FIXED = 2 + 4 + 8 + 8


class McapFile:
    """Write one MCAP file to ``stream`` (see the module docstring)."""

    def __init__(
        self,
        stream: BinaryIO,
        *,
        chunk_size: int = 1024 * 1024,
        compression: str = "zstd",
    ) -> None:
        if compression not in COMPRESSIONS:
            raise ValueError(f"compression {compression!r}: one of {', '.join(COMPRESSIONS)}")
        self._stream = stream
        self._pos = 0
        self._chunk_size = chunk_size
        self._compression = "" if compression == "none" else compression
        self._compress = _compressor(compression)
        self._chunk = bytearray()
        self._index: dict[int, list[int]] = {}  # channel -> log time, offset, log time, ...
        self._schemas: list[Schema] = []
        self._channels: list[Channel] = []
        self._chunk_indexes: list[ChunkIndex] = []
        self._metadata_indexes: list[MetadataIndex] = []
        self._counts: dict[int, int] = {}
        self._messages = 0
        self._start = 0
        self._end = 0
        self._chunks = 0

    # -- records outside the chunks ------------------------------------------------------
    def _write(self, data: bytes | bytearray) -> None:
        self._stream.write(data)
        self._pos += len(data)

    def start(self, profile: str = "", library: str = "") -> None:
        rb = RecordBuilder()
        Header(profile, library).write(rb)
        self._write(MAGIC + rb.end())

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        rb = RecordBuilder()
        Metadata(name=name, metadata=data).write(rb)
        record = rb.end()
        self._metadata_indexes.append(MetadataIndex(self._pos, len(record), name))
        self._write(record)

    # -- records inside the open chunk ---------------------------------------------------
    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        schema = Schema(id=len(self._schemas) + 1, data=data, encoding=encoding, name=name)
        self._schemas.append(schema)
        self._chunk_record(schema)
        return schema.id

    def register_channel(
        self,
        topic: str,
        message_encoding: str,
        schema_id: int,
        metadata: dict[str, str] | None = None,
    ) -> int:
        channel = Channel(
            id=len(self._channels) + 1,
            topic=topic,
            message_encoding=message_encoding,
            schema_id=schema_id,
            metadata=dict(metadata or {}),
        )
        self._channels.append(channel)
        self._chunk_record(channel)
        return channel.id

    def _chunk_record(self, record: Schema | Channel) -> None:
        rb = RecordBuilder()
        record.write(rb)
        self._chunk += rb.end()
        if len(self._chunk) > self._chunk_size:
            self._finish_chunk()

    def add_message(
        self, channel_id: int, log_time: int, data: bytes, publish_time: int, sequence: int
    ) -> None:
        chunk = self._chunk
        offset = len(chunk)
        chunk += _MESSAGE.pack(
            Opcode.MESSAGE,
            _MESSAGE_FIXED + len(data),
            channel_id,
            sequence,
            log_time,
            publish_time,
        )
        chunk += data
        index = self._index.get(channel_id)
        if index is None:
            index = self._index[channel_id] = []
        index.append(log_time)
        index.append(offset)
        if len(chunk) > self._chunk_size:
            self._finish_chunk()

    # -- chunks ----------------------------------------------------------------------------
    def _finish_chunk(self) -> None:
        """Compress and write the open chunk and its message indexes; the chunk's times
        and the statistics come from the index entries (log time, offset, ...)."""
        if not self._index:
            return
        start = min(min(e[0::2]) for e in self._index.values())
        end = max(max(e[0::2]) for e in self._index.values())
        counts = self._counts
        for cid, entries in self._index.items():
            counts[cid] = counts.get(cid, 0) + len(entries) // 2
        if self._messages:
            self._start, self._end = min(self._start, start), max(self._end, end)
        else:
            self._start, self._end = start, end
        self._messages += sum(len(e) for e in self._index.values()) // 2
        raw = bytes(self._chunk)
        packed = self._compress(raw) if self._compress is not None else raw
        rb = RecordBuilder()
        Chunk(
            compression=self._compression,
            data=packed,
            message_start_time=start,
            message_end_time=end,
            uncompressed_crc=zlib.crc32(raw),
            uncompressed_size=len(raw),
        ).write(rb)
        record = rb.end()
        chunk_start = self._pos
        self._write(record)
        index_start = self._pos
        offsets: dict[int, int] = {}
        parts = []
        length = 0
        for cid, entries in self._index.items():
            offsets[cid] = index_start + length
            n = len(entries)
            part = struct.pack(f"<BQHI{n}Q", Opcode.MESSAGE_INDEX, 6 + 8 * n, cid, 8 * n, *entries)
            parts.append(part)
            length += len(part)
        self._write(b"".join(parts))
        self._chunk_indexes.append(
            ChunkIndex(
                message_start_time=start,
                message_end_time=end,
                chunk_start_offset=chunk_start,
                chunk_length=len(record),
                message_index_offsets=offsets,
                message_index_length=length,
                compression=self._compression,
                compressed_size=len(packed),
                uncompressed_size=len(raw),
            )
        )
        self._chunks += 1
        self._chunk = bytearray()
        self._index = {}

    def flush(self) -> None:
        """Finish the open chunk (if it holds a message) and flush the stream."""
        self._finish_chunk()
        self._stream.flush()

    def finish(self) -> None:
        """The last chunk, the data end, the summary and the footer (the stream stays open)."""
        self._finish_chunk()
        rb = RecordBuilder()
        DataEnd(0).write(rb)
        self._write(rb.end())
        summary_start = self._pos
        sb = RecordBuilder()
        offsets: list[SummaryOffset] = []

        def group(opcode: Opcode, records: list) -> None:
            start = sb.count
            for r in records:
                r.write(sb)
            offsets.append(SummaryOffset(opcode, summary_start + start, sb.count - start))

        group(Opcode.SCHEMA, self._schemas)
        group(Opcode.CHANNEL, self._channels)
        group(Opcode.STATISTICS, [self._statistics()])
        group(Opcode.CHUNK_INDEX, self._chunk_indexes)
        group(Opcode.ATTACHMENT_INDEX, [])
        group(Opcode.METADATA_INDEX, self._metadata_indexes)
        summary_offset_start = summary_start + sb.count
        for o in offsets:
            o.write(sb)
        summary = sb.end()
        crc = zlib.crc32(summary)
        crc = zlib.crc32(
            struct.pack("<BQQQ", Opcode.FOOTER, 20, summary_start, summary_offset_start), crc
        )
        self._write(summary)
        fb = RecordBuilder()
        Footer(summary_start, summary_offset_start, crc).write(fb)
        self._write(fb.end() + MAGIC)
        self._stream.flush()

    def _statistics(self) -> Statistics:
        return Statistics(
            attachment_count=0,
            channel_count=len(self._channels),
            channel_message_counts=dict(self._counts),
            chunk_count=self._chunks,
            message_count=self._messages,
            message_end_time=self._end,
            message_start_time=self._start,
            metadata_count=len(self._metadata_indexes),
            schema_count=len(self._schemas),
        )


def _compressor(compression: str):
    if compression == "zstd":
        return zstandard.ZstdCompressor(level=3).compress
    if compression == "lz4":
        import lz4.frame

        return lz4.frame.compress
    return None
