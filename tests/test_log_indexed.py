"""hilnav.log.indexed reads an indexed MCAP file as the mcap library's reader does: the
same messages in the same log-time order (chunks overlapping in time, equal times, topic
filters, every compression)."""

from __future__ import annotations

import io
import random

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from hilnav.log.indexed import iter_indexed

COMPRESSION = {
    "zstd": CompressionType.ZSTD,
    "lz4": CompressionType.LZ4,
    "none": CompressionType.NONE,
}


def log_bytes(seed: int, compression: str) -> bytes:
    """Messages on five channels whose log times go back and forth and repeat, cut into
    small chunks that overlap in time."""
    rng = random.Random(seed)
    buf = io.BytesIO()
    w = Writer(buf, chunk_size=700, compression=COMPRESSION[compression])
    w.start()
    sid = w.register_schema("s", "jsonschema", b"{}")
    cids = [w.register_channel(f"/r{i % 2}/t{i}", "json", sid if i else 0) for i in range(5)]
    t = 10**18
    for i in range(1500):
        t += rng.choice((0, 0, 1, 5, 1000, -2000, 3_000_000))
        cid = rng.choice(cids)
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(40)))
        w.add_message(cid, max(t, 0), data, t + 7, i)
        if rng.random() < 0.01:
            w.flush()
    w.finish()
    return buf.getvalue()


def library(data: bytes, topics=None) -> list[tuple]:
    reader = make_reader(io.BytesIO(data))
    return [
        (s.name if s else None, c.topic, m.log_time, m.publish_time, m.sequence, m.data)
        for s, c, m in reader.iter_messages(topics=topics, log_time_order=True)
    ]


def ours(data: bytes, topics=None) -> list[tuple]:
    f = io.BytesIO(data)
    summary = make_reader(f).get_summary()
    return [
        (s.name if s else None, c.topic, log, pub, seq, d)
        for s, c, log, pub, seq, d in iter_indexed(f, summary, topics)
    ]


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_same_messages_in_the_same_order_as_the_library(compression, seed):
    data = log_bytes(seed, compression)
    expected = library(data)
    assert len(expected) == 1500 and ours(data) == expected
    topics = ["/r1/t1", "/r0/t4"]
    assert ours(data, topics) == library(data, topics)
    assert ours(data, []) == []
