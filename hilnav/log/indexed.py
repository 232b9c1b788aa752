"""The messages of an indexed MCAP file in log-time order, its chunks parsed by hand.

The mcap library's ``SeekingReader.iter_messages(log_time_order=True)`` wraps every
message in a Python object ordered by a Python ``__lt__`` on its heap, and builds a
``Message`` record per message: most of a log reader's time. :func:`iter_indexed` gives
the same messages in the same order from the file's summary (its chunk indexes, schemas
and channels): each chunk is read, decompressed and split into messages with
``struct.unpack_from``, and the messages are merged on plain tuples
``(log time, chunk offset, index in the chunk)``, the library's order (a chunk opens when
its first log time, then its offset, comes up, as the library's queue does), so only the
chunks that overlap in time are held in memory. CRCs are not checked (nor are they by
the library's reader by default).
"""

from __future__ import annotations

import heapq
import struct
from collections.abc import Iterable, Iterator
from typing import BinaryIO

import zstandard
from mcap.records import Channel, ChunkIndex, Schema
from mcap.summary import Summary

_RECORD = struct.Struct("<BQ")  # opcode, length
_MESSAGE = struct.Struct("<HIQQ")  # channel, sequence, log time, publish time
_CHUNK = struct.Struct("<QQQII")  # start, end, uncompressed size, CRC, compression length
_U64 = struct.Struct("<Q")
_OP_MESSAGE = 0x05

# (log time, chunk offset, index, channel id, sequence, publish time, data)
Item = tuple[int, int, int, int, int, int, bytes]


def iter_indexed(
    stream: BinaryIO, summary: Summary, topics: Iterable[str] | None = None
) -> Iterator[tuple[Schema | None, Channel, int, int, int, bytes]]:
    """(schema, channel, log time, publish time, sequence, data) of every message on
    ``topics`` (all when None), in log-time order; ValueError on a chunk it cannot read."""
    channels = summary.channels
    wanted = None
    if topics is not None:
        names = set(topics)
        wanted = {cid for cid, ch in channels.items() if ch.topic in names}
    chunks = sorted(
        (
            c
            for c in summary.chunk_indexes
            if wanted is None or not wanted.isdisjoint(c.message_index_offsets)
        ),
        key=lambda c: (c.message_start_time, c.chunk_start_offset),
    )
    schemas = summary.schemas
    heap: list[Item] = []
    k, n = 0, len(chunks)
    decompressor = zstandard.ZstdDecompressor()
    while k < n or heap:
        while k < n and (
            not heap or (chunks[k].message_start_time, chunks[k].chunk_start_offset) <= heap[0]
        ):
            for item in _chunk_messages(stream, chunks[k], wanted, decompressor):
                heapq.heappush(heap, item)
            k += 1
        if not heap:
            continue
        log, _, _, cid, seq, pub, data = heapq.heappop(heap)
        channel = channels.get(cid)
        if channel is None:
            continue  # a message on a channel the summary does not know
        schema = schemas.get(channel.schema_id) if channel.schema_id else None
        yield schema, channel, log, pub, seq, data


def _chunk_messages(
    stream: BinaryIO,
    index: ChunkIndex,
    wanted: set[int] | None,
    decompressor: zstandard.ZstdDecompressor,
) -> list[Item]:
    stream.seek(index.chunk_start_offset)
    raw = stream.read(index.chunk_length)
    if len(raw) < index.chunk_length:
        raise ValueError(f"chunk at {index.chunk_start_offset}: file ends inside it")
    _start, _end, size, _crc, clen = _CHUNK.unpack_from(raw, 9)
    p = 9 + _CHUNK.size
    compression = raw[p : p + clen].decode()
    p += clen
    (length,) = _U64.unpack_from(raw, p)
    body = raw[p + 8 : p + 8 + length]
    if compression == "zstd":
        data = decompressor.decompress(body, max_output_size=size)
    elif compression == "lz4":
        import lz4.frame

        data = lz4.frame.decompress(body)
    elif compression == "":
        data = body
    else:
        raise ValueError(f"chunk at {index.chunk_start_offset}: compression {compression!r}")
    out: list[Item] = []
    offset = index.chunk_start_offset
    pos, end, i = 0, len(data), 0
    unpack_record, unpack_message = _RECORD.unpack_from, _MESSAGE.unpack_from
    while pos + 9 <= end:
        op, rlen = unpack_record(data, pos)
        if op == _OP_MESSAGE:
            cid, seq, log, pub = unpack_message(data, pos + 9)
            if wanted is None or cid in wanted:
                out.append((log, offset, i, cid, seq, pub, data[pos + 31 : pos + 9 + rlen]))
        pos += 9 + rlen
        i += 1
    return out
