"""Every codec under mutation fuzzing (hypothesis, derandomized): no exception escapes, no
frame is invented, every intact frame is decoded, and by the feed that completes it.

The mutations and checks are in tests/codec_fuzz.py, the clean streams in
tests/codec_streams.py and tests/nmea_stream.py (the drivers' codecs) and
tests/command_streams.py (the fakes' command parsers); bench/fuzz.py runs the same over
many more streams.
"""

from __future__ import annotations

import random
import struct

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drivers.irboard.serialframe import SYNC_DATA
from tests.codec_fuzz import KINDS, Piece, Tally, check, chunked, fuzz_one
from tests.codec_streams import STREAMS, Gyro
from tests.command_streams import COMMAND_STREAMS

ADAPTERS = {name: cls() for name, cls in {**STREAMS, **COMMAND_STREAMS}.items()}
FUZZ = settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)


def _clean(t: Tally) -> tuple[int, ...]:
    return (t.crashes, t.phantoms, t.lost_after_damage, t.lost_before_damage, t.late)


@pytest.mark.parametrize("name", sorted(ADAPTERS))
@FUZZ
@given(rng=st.randoms(use_true_random=False), kinds=st.sets(st.sampled_from(KINDS), min_size=1))
def test_mutated_streams_cost_only_the_damaged_frames(name, rng, kinds):
    t = fuzz_one(ADAPTERS[name], rng, sorted(kinds))
    assert _clean(t) == (0, 0, 0, 0, 0), t


@pytest.mark.parametrize("name", sorted(ADAPTERS))
@FUZZ
@given(rng=st.randoms(use_true_random=False))
def test_clean_streams_in_any_chunks_decode_whole(name, rng):
    ad = ADAPTERS[name]
    codec = ad.new()
    data = [p.data for p in ad.frames]
    feeds = data if ad.framed else chunked(b"".join(data), rng)
    keys = [k for c in feeds for k in ad.feed(codec, c, 0)] + ad.finish(codec)
    assert keys == [p.key for p in ad.frames if p.key is not None]
    s = codec.stats
    assert (s.bad_checksums, s.frames_lost, s.malformed, s.duplicates) == (0, 0, 0, 0), s


@pytest.mark.parametrize("name", ["ir_serial", "ir_can"])
@FUZZ
@given(data=st.data())
def test_sequence_numbers_count_drops_and_duplicates(name, data):
    """Frames dropped are counted lost, repeated ones counted as duplicates and not decoded."""
    ad = ADAPTERS[name]
    n = len(ad.frames)
    drop = data.draw(st.sets(st.integers(0, n - 1), max_size=3))
    dup = data.draw(st.sets(st.integers(0, n - 1), max_size=3)) - drop
    codec = ad.new()
    keys = []
    for i, p in enumerate(ad.frames):
        for _ in range(0 if i in drop else 2 if i in dup else 1):
            keys += ad.feed(codec, p.data, i)
    kept = [p.key for i, p in enumerate(ad.frames) if i not in drop and p.key is not None]
    assert keys == kept
    mask = 0xF if ad.framed else 0xFFFF
    seqs = [k[1] for k in kept]
    gaps = [(seqs[j + 1] - seqs[j] - 1) & mask for j in range(len(seqs) - 1)]
    assert codec.stats.frames_lost == sum(gaps)
    samples = [i for i in dup if _is_sample(ad, ad.frames[i])]  # other boards' samples too
    assert codec.stats.duplicates == len(samples)


def _is_sample(ad, p: Piece) -> bool:
    return p.key is not None if ad.framed else p.data[:2] == SYNC_DATA


class _Broken(Gyro):
    """The gyro codec with one fault injected, to show the checks see it."""

    def __init__(self, fault: str) -> None:
        self.fault = ""  # the clean frames' keys first, without the fault
        self.held: list = []
        super().__init__()
        self.fault = fault

    def feed(self, codec, chunk, stamp):
        keys = super().feed(codec, chunk, stamp)
        if self.fault == "crash":
            raise OverflowError("injected")
        if self.fault == "phantom":
            keys.append((0.0, 0.0))
        if self.fault == "lost":
            keys = [k for k in keys if k != self.frames[3].key]
        if self.fault == "late":
            keys, self.held = self.held, keys
        return keys

    def finish(self, codec):
        held, self.held = self.held, []
        return held


@pytest.mark.parametrize("fault", ["crash", "phantom", "lost", "late"])
def test_the_checks_see_each_fault(fault):
    ad = _Broken(fault)
    pieces = list(ad.frames)
    bad = bytearray(pieces[5].data)
    bad[2] ^= 1
    pieces[5] = Piece(bytes(bad), None, False)  # one frame with a bad checksum
    t = check(ad, pieces, random.Random(7))
    seen = {
        "crash": t.crashes,
        "phantom": t.phantoms,
        "lost": t.lost_before_damage + t.lost_after_damage,
        "late": t.late,
    }
    assert {k for k, v in seen.items() if v} == {fault}, t


def test_a_damaged_frame_passing_the_checks_may_swallow_the_next():
    """A gyro packet (18000, -18000) has the checksum FF FF: cut by one byte, the next
    header's first FF completes it and the next packet loses its header. The codec cannot
    tell; the checks count it as swallowed, not lost."""
    ad = ADAPTERS["cruzcore"]
    cut = struct.pack("<2shhH", b"\xff\xff", 18000, -18000, 0xFFFF)[:-1]
    pieces = [*ad.frames[:3], Piece(cut, None, False), *ad.frames[3:]]
    t = check(ad, pieces, random.Random(0))
    assert (t.swallowed, t.accepted_damaged, t.lost_after_damage, t.phantoms) == (1, 1, 0, 0)
