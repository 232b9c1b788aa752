"""hilnav.log.mcap_file writes the very bytes the mcap library's Writer writes."""

from __future__ import annotations

import io
import random

import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from hilnav.log.mcap_file import McapFile

LIBRARY = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}


def calls(seed: int) -> list[tuple]:
    """A seeded mix of schemas, channels, messages (times out of order too), metadata and
    flushes, small chunks so that several are cut by size."""
    rng = random.Random(seed)
    out: list[tuple] = [("schema", "hilnav.A", "jsonschema", b'{"type":"object"}')]
    out.append(("schema", "empty", "", b""))
    channels = 0
    t = 1_700_000_000_000_000_000
    for i in range(600):
        r = rng.random()
        if channels == 0 or r < 0.01:
            channels += 1
            meta = {"k": "v"} if channels % 2 else {}
            out.append(("channel", f"/r1/t{channels}", "json", 1 + channels % 2, meta))
        elif r < 0.015:
            out.append(("metadata", f"m{i}", {"a": str(i), "b": "x" * rng.randrange(5)}))
        elif r < 0.03:
            out.append(("flush",))
        else:
            t += rng.randrange(-3_000_000, 20_000_000)
            data = bytes(rng.randrange(256) for _ in range(rng.randrange(0, 80)))
            pub = t + rng.randrange(0, 1000)
            out.append(("message", rng.randrange(1, channels + 1), t, data, pub, i))
    return out


def play(w, script) -> None:
    w.start(profile="", library="hilnav")
    for c in script:
        if c[0] == "schema":
            w.register_schema(name=c[1], encoding=c[2], data=c[3])
        elif c[0] == "channel":
            w.register_channel(topic=c[1], message_encoding=c[2], schema_id=c[3], metadata=c[4])
        elif c[0] == "metadata":
            w.add_metadata(c[1], c[2])
        elif c[0] == "flush":
            w.flush()
        else:
            w.add_message(
                channel_id=c[1], log_time=c[2], data=c[3], publish_time=c[4], sequence=c[5]
            )
    w.finish()


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
@pytest.mark.parametrize("seed", [1, 2])
def test_same_bytes_as_the_mcap_library(compression, seed):
    script = calls(seed)
    ours, theirs = io.BytesIO(), io.BytesIO()
    play(McapFile(ours, chunk_size=2048, compression=compression), script)
    play(Writer(theirs, chunk_size=2048, compression=LIBRARY[compression]), script)
    assert ours.getvalue() == theirs.getvalue()
    ours.seek(0)
    reader = make_reader(ours)
    n = sum(1 for _ in reader.iter_messages())
    assert n == sum(1 for c in script if c[0] == "message") > 500
    assert reader.get_summary().statistics.chunk_count > 3


def test_an_empty_file_is_valid():
    ours, theirs = io.BytesIO(), io.BytesIO()
    play(McapFile(ours), [])
    play(Writer(theirs), [])
    assert ours.getvalue() == theirs.getvalue()
