"""Mutation fuzzing of the device codecs: damaged copies of clean streams, and their checks.

Shared by tests/test_fuzz_codecs.py (hypothesis draws the choices) and bench/fuzz.py (one
seeded ``random.Random`` per stream). A stream is a list of pieces: the clean frames of an
adapter (tests/codec_streams.py), some of them replaced by damaged pieces: byte flips,
inserts, deletes, truncations, garbage splices, length fields set to their maximum,
checksum-valid field mutations (the checksum recomputed after the change), duplicates, and
drops (an empty damaged piece marks where a frame was). The bytes are fed in random
chunks. Per stream the checks count:

- ``crashes``: an exception escaped the codec;
- ``phantoms``: a message that is neither an intact frame's nor that of a frame starting
  inside a damaged piece and passing the protocol's checks; whether it passes is judged by
  the adapter's ``valid``, by re-encoding with the project's encoders, not by the codec;
- ``accepted_damaged``: messages of such damaged frames. The codec cannot tell them from
  real ones (NMEA's XOR does not see two equal bytes deleted; a field mutation keeps the
  checksum right; CAN data has no checksum of its own), so they are no fault;
- ``lost_after_damage`` / ``lost_before_damage``: intact frames not decoded, after the
  first damaged piece or before it;
- ``swallowed``: intact frames lost because a damaged frame passing the protocol's checks
  overlaps their first bytes (CruzCore's ``FF FF`` header can be the end of a checksum; a
  cut IR frame's CRC can match with the next frame's first byte): the codec cannot tell
  which of the two is real, so this is no fault either;
- ``late``: intact frames decoded by a later ``feed`` than the one that completed them.
"""

from __future__ import annotations

import bisect
import random
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, fields
from typing import Any, Protocol

Key = Hashable
KINDS = ("flip", "insert", "delete", "truncate", "splice", "maxlen", "field", "duplicate", "drop")


@dataclass(frozen=True, slots=True)
class Piece:
    """Bytes of the stream: an intact clean frame (``key``: its message, None if it gives
    none) or a damaged piece."""

    data: bytes
    key: Key | None = None
    intact: bool = True


class Adapter(Protocol):
    """One codec under test: its clean frames and how to feed it (tests/codec_streams.py)."""

    name: str
    framed: bool  # True: each piece is one frame fed on its own (CAN); False: a byte stream
    sync: bytes  # how a frame starts (for the search of damaged frames that pass checks)
    special: bytes  # bytes the garbage is salted with (sync bytes, separators)
    frames: Sequence[Piece]

    def new(self) -> Any: ...

    def feed(self, codec: Any, chunk: bytes, stamp: int) -> list[Key]: ...

    def finish(self, codec: Any) -> list[Key]: ...

    def lengths(self, data: bytes, p: int) -> list[int]: ...

    def valid(self, frame: bytes) -> bool: ...

    def field(self, frame: bytes, rng: random.Random) -> bytes | None: ...

    def maxlen(self, frame: bytes, rng: random.Random) -> bytes | None: ...

    def garbage(self, rng: random.Random) -> list[bytes]: ...


@dataclass
class Tally:
    """Figures over many streams of one codec."""

    streams: int = 0
    crashes: int = 0
    phantoms: int = 0
    lost_after_damage: int = 0
    lost_before_damage: int = 0
    swallowed: int = 0
    late: int = 0
    accepted_damaged: int = 0
    seconds: float = 0.0
    first_crash: str = ""

    def add(self, other: Tally) -> None:
        for f in fields(self):
            if f.name == "first_crash":
                self.first_crash = self.first_crash or other.first_crash
            else:
                setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))


def random_bytes(rng: random.Random, n: int) -> bytes:
    return bytes(rng.getrandbits(8) for _ in range(n))


def salted(rng: random.Random, n: int, special: bytes) -> bytes:
    """``n`` random bytes, about a third of them from ``special``."""
    return bytes(
        rng.choice(special) if rng.random() < 0.3 else rng.getrandbits(8) for _ in range(n)
    )


class Stream:
    """Defaults of the adapters: byte stream, salted garbage, keys of the clean frames."""

    name = ""
    framed = False
    sync = b""
    special = b""
    frames: list[Piece] = []
    codec_type: Callable[[], Any]

    def new(self) -> Any:
        return self.codec_type()

    def key(self, msg: Any) -> Key:
        """What of a message a clean frame fixes (not what depends on earlier frames)."""
        return msg

    def feed(self, codec: Any, chunk: bytes, stamp: int) -> list[Key]:
        return [self.key(m) for m in codec.feed(chunk, stamp)]

    def finish(self, codec: Any) -> list[Key]:
        return []

    def garbage(self, rng: random.Random) -> list[bytes]:
        n = rng.choice((rng.randint(1, 16), rng.randint(1, 64), rng.randint(100, 300)))
        return [salted(rng, n, self.special)]

    def _keyed(self, frames: list[bytes]) -> list[Piece]:
        """Pieces of the clean frames, each with its message's key (all keys different)."""
        out = []
        for f in frames:
            codec = self.new()
            keys = self.feed(codec, f, 0) + self.finish(codec)
            assert len(keys) <= 1, keys
            out.append(Piece(f, keys[0] if keys else None))
        assert len({p.key for p in out if p.key is not None}) == sum(p.key is not None for p in out)
        return out


# ------------------------------------------------------------------ mutations


def _flip(ad: Adapter, p: Piece, rng: random.Random) -> list[Piece]:
    d = bytearray(p.data)
    if d:
        d[rng.randrange(len(d))] ^= rng.randint(1, 255)
    return [Piece(bytes(d), None, False)]


def _insert(ad: Adapter, p: Piece, rng: random.Random) -> list[Piece]:
    i = rng.randint(0, len(p.data))
    return [
        Piece(p.data[:i] + salted(rng, rng.randint(1, 8), ad.special) + p.data[i:], None, False)
    ]


def _delete(ad: Adapter, p: Piece, rng: random.Random) -> list[Piece]:
    if not p.data:
        return [p]
    i = rng.randrange(len(p.data))
    return [Piece(p.data[:i] + p.data[i + rng.randint(1, 4) :], None, False)]


def _truncate(ad: Adapter, p: Piece, rng: random.Random) -> list[Piece]:
    return [Piece(p.data[: rng.randrange(len(p.data))] if p.data else b"", None, False)]


def _splice(ad: Adapter, p: Piece, rng: random.Random) -> list[Piece]:
    junk = [Piece(g, None, False) for g in ad.garbage(rng)]
    where = rng.randrange(2 if ad.framed else 3)
    if where == 0:
        return [*junk, p]
    if where == 1:
        return [p, *junk]
    i = rng.randint(0, len(p.data))
    j = rng.randint(i, len(p.data))
    return [Piece(p.data[:i] + b"".join(g.data for g in junk) + p.data[j:], None, False)]


def _special(method: str) -> Callable[[Adapter, Piece, random.Random], list[Piece]]:
    def mutate(ad: Adapter, p: Piece, rng: random.Random) -> list[Piece]:
        data = getattr(ad, method)(p.data, rng) if p.intact else None
        return _flip(ad, p, rng) if data is None else [Piece(data, None, False)]

    return mutate


def _duplicate(ad: Adapter, p: Piece, rng: random.Random) -> list[Piece]:
    return [p, Piece(p.data, None, False)]


def _drop(ad: Adapter, p: Piece, rng: random.Random) -> list[Piece]:
    return [Piece(b"", None, False)]


MUTATORS = {
    "flip": _flip,
    "insert": _insert,
    "delete": _delete,
    "truncate": _truncate,
    "splice": _splice,
    "maxlen": _special("maxlen"),
    "field": _special("field"),
    "duplicate": _duplicate,
    "drop": _drop,
}


def mutate(
    ad: Adapter, rng: random.Random, kinds: Sequence[str] = KINDS, most: int = 3
) -> list[Piece]:
    """The clean frames with 1..``most`` mutations of the given kinds."""
    pieces = list(ad.frames)
    for _ in range(rng.randint(1, most)):
        k = rng.randrange(len(pieces))
        pieces[k : k + 1] = MUTATORS[rng.choice(kinds)](ad, pieces[k], rng)
    return pieces


def chunked(data: bytes, rng: random.Random) -> list[bytes]:
    """``data`` whole, in chunks of one fixed size, or in chunks of random sizes."""
    mode = rng.randrange(3)
    if mode == 0:
        return [data]
    size = rng.randint(1, 9)
    out = []
    i = 0
    while i < len(data):
        if mode == 2:
            size = rng.randint(1, 64)
        out.append(data[i : i + size])
        i += size
    return out


# ------------------------------------------------------------------ running and checking


def fuzz_one(ad: Adapter, rng: random.Random, kinds: Sequence[str] = KINDS) -> Tally:
    """One mutated stream through a fresh codec; its figures."""
    return check(ad, mutate(ad, rng, kinds), rng)


def check(ad: Adapter, pieces: list[Piece], rng: random.Random) -> Tally:
    """Feed ``pieces`` (chunked at random) to a fresh codec and count what went wrong."""
    feeds: list[bytes] = []
    done: list[int] = []
    if ad.framed:  # one feed per frame; a drop marker feeds nothing
        for p in pieces:
            if p.data or p.intact:
                feeds.append(p.data)
            done.append(len(feeds) - 1)
    else:
        feeds = chunked(b"".join(p.data for p in pieces), rng)
        ends = []
        total = 0
        for c in feeds:
            total += len(c)
            ends.append(total)
        for end in _ends(pieces):
            done.append(bisect.bisect_left(ends, end))
    out: list[tuple[Key, int]] = []
    t = Tally(streams=1)
    try:
        codec = ad.new()
        for c, chunk in enumerate(feeds):
            out += [(k, c) for k in ad.feed(codec, chunk, c)]
        out += [(k, len(feeds)) for k in ad.finish(codec)]
    except Exception as exc:  # the very thing a fuzzer looks for
        t.crashes = 1
        t.first_crash = f"{ad.name}: {type(exc).__name__}: {exc}"
        return t
    _match(ad, pieces, done, out, t)
    return t


def _ends(pieces: list[Piece]) -> list[int]:
    """Offset just past each piece in the stream."""
    out = []
    total = 0
    for p in pieces:
        total += len(p.data)
        out.append(total)
    return out


def _match(ad: Adapter, pieces: list[Piece], done: list[int], out: list, t: Tally) -> None:
    """Align the decoded messages with the intact frames (keys are unique in a clean stream)."""
    first_damage = next((i for i, p in enumerate(pieces) if not p.intact), len(pieces))
    intact = [(i, p.key, done[i]) for i, p in enumerate(pieces) if p.intact and p.key is not None]
    where = {key: j for j, (_, key, _) in enumerate(intact)}
    found: list[tuple[int, int, list[Key]]] | None = None
    ends = _ends(pieces)
    ptr = 0

    def lose(upto: int) -> None:
        nonlocal found
        for i, _, _ in intact[ptr:upto]:
            found = valid_damaged(ad, pieces) if found is None else found
            start = ends[i] - len(pieces[i].data)
            if any(a <= start < b for a, b, _ in found):
                t.swallowed += 1
            elif i > first_damage:
                t.lost_after_damage += 1
            else:
                t.lost_before_damage += 1

    for key, c in out:
        j = where.get(key, -1)
        if j >= ptr:
            lose(j)
            t.late += c > intact[j][2]
            ptr = j + 1
            continue
        found = valid_damaged(ad, pieces) if found is None else found
        if any(key in keys for _, _, keys in found):
            t.accepted_damaged += 1
        else:
            t.phantoms += 1
    lose(len(intact))


def valid_damaged(ad: Adapter, pieces: list[Piece]) -> list[tuple[int, int, list[Key]]]:
    """(start, end, messages) of every frame passing the protocol's checks that starts in a
    damaged piece (for a framed codec, of every damaged frame: start and end are 0)."""
    found = []
    if ad.framed:
        for p in pieces:
            if not p.intact and ad.valid(p.data):
                found.append((0, 0, alone(ad, p.data)))
        return found
    data = b"".join(p.data for p in pieces)
    for p, end in zip(pieces, _ends(pieces), strict=True):
        if not p.intact:
            q = data.find(ad.sync, end - len(p.data))
            while 0 <= q < end:
                for n in ad.lengths(data, q):
                    if ad.valid(data[q : q + n]):
                        found.append((q, q + n, alone(ad, data[q : q + n])))
                q = data.find(ad.sync, q + 1)
    return found


def alone(ad: Adapter, data: bytes) -> list[Key]:
    """Messages a fresh codec makes of ``data`` (one valid frame) fed at once."""
    try:
        codec = ad.new()
        return ad.feed(codec, data, 0) + ad.finish(codec)
    except Exception:
        return []
