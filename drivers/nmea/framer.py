"""NMEA byte stream -> checked sentences, each given to a reader chosen by its address.

Framing: a sentence starts at ``$`` and ends at LF (CR optional). A line is dropped and
counted when it is overlong (over ``max_line`` bytes from ``$`` to the checksum, CR and LF
not counted; default 128: Skytraq's PSTI sentences are 108), holds non-printable bytes
(binary noise), or fails the XOR checksum; a line with no checksum at all is accepted only
with ``require_checksum=False``. A sentence cut short by the start of the next
(``$GPGGA,12$GPRMC,...``) is dropped and the next one kept, so the framer is back in step
within one sentence. Bytes outside sentences are skipped and counted. A run of complete
lines is checked at once (with numpy from 512 bytes on), a line out of the ordinary on
its own path.

A sentence goes to its route, ``routes[address](rest, stamp_ns, out)``, ``rest`` the text
of its fields (between the first comma and the ``*``): the codec's routes are its readers
(drivers/nmea/codec.py); :meth:`NmeaFramer.feed` and :meth:`NmeaFramer.feed_raw` collect
the sentences instead.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np

from drivers.base import CodecStats
from drivers.nmea.memo import table
from drivers.nmea.sentences import Sentence

_HEX = frozenset(b"0123456789ABCDEFabcdef")
_HEX2 = {
    f"{a}{b}": int(f"{a}{b}", 16)
    for a in "0123456789ABCDEFabcdef"
    for b in "0123456789ABCDEFabcdef"
}
_sentence = tuple.__new__  # Sentence(...) without the NamedTuple's Python-level __new__
_NUMPY_FROM = 512  # bytes from which a run's prefix XOR is computed with numpy


# byte -> its value as a hex digit, -1 for any other byte
_HEXVAL = np.full(256, -1, dtype=np.int16)
for _i, _c in enumerate(b"0123456789ABCDEF"):
    _HEXVAL[_c] = _i
for _i, _c in enumerate(b"abcdef"):
    _HEXVAL[_c] = 10 + _i
# what the vectorised checks say of a line: a sentence with the right checksum (its
# address still to be checked), a wrong checksum, anything else (the per-line path)
GOOD, BAD_SUM, OTHER = 0, 1, 2
_ADDRESS_CACHE = 256
_ADDRESSES: dict[str, tuple[str, str] | tuple[()]] = table({})


def _address(address: str) -> tuple[str, str] | tuple[()]:
    """(talker, type) of a sentence's address ("GP", "GGA"; "P", "GRMZ" for ``$PGRMZ``), or
    () when it is not one (fewer than 3 characters, or not all letters and digits)."""
    tk = _ADDRESSES.get(address)
    if tk is None:
        if len(address) < 3 or not (address.isalnum() and address.isascii()):
            tk = ()
        elif address[0] == "P":  # proprietary: $P<maker><type>
            tk = ("P", address[1:])
        else:
            tk = (address[:2], address[2:])
        if len(_ADDRESSES) >= _ADDRESS_CACHE:
            _ADDRESSES.clear()
        _ADDRESSES[address] = tk
    return tk


def _prefix_xor(data: bytes) -> bytes:
    """p[i] = data[0] ^ ... ^ data[i] (as bytes); p[j] ^ p[i] is the XOR of data[i+1..j]."""
    out = bytearray(len(data))
    c = 0
    for i, b in enumerate(data):
        c ^= b
        out[i] = c
    return bytes(out)


def _classify(region: bytes, max_line: int) -> tuple[np.ndarray, ...]:
    """Every line of a run of complete ASCII lines, checked at once with numpy: (starts,
    ends without a CR, verdicts, address lengths, keys). A GOOD line is ``$...*HH`` of
    printable bytes, one ``$``, no longer than ``max_line``, the XOR of the bytes between
    ``$`` and ``*`` equal to HH; BAD_SUM fails only the XOR; OTHER is anything else (the
    per-line path). The address (up to the first comma) is checked by the caller: of a
    line whose first comma is one of the 8 bytes after the ``$`` (and before the ``*``),
    the address's length and :func:`_key`, else -1 for both. (A run of at least 8 bytes:
    the framer checks runs from 512 bytes on this way.)"""
    a = np.frombuffer(region, dtype=np.uint8)
    size = len(a)
    nl = np.flatnonzero(a == 10)
    starts = np.empty(len(nl) + 1, dtype=np.intp)
    starts[0] = 0
    starts[1:] = nl + 1
    ends = np.empty(len(nl) + 1, dtype=np.intp)
    ends[:-1] = nl
    ends[-1] = size
    ends -= (ends > starts) & (a[ends - 1] == 13)  # a CR ends the line, not part of it
    n = ends - starts
    ok = (n >= 5) & (n <= max_line)  # "$" + address + "*HH"
    star = np.where(ok, ends - 3, 0)
    ok &= (a[starts * ok] == 36) & (a[star] == 42)  # "$" ... "*"
    # no "$" but the first and no byte that is not printable: the count of such bytes
    # from a line's start to the next's, less its end (CR, LF), is 1
    odd = ((a - np.uint8(32) > 94) | (a == 36)).view(np.uint8)  # (uint8 wraps below 32)
    first = np.minimum(starts, size - 1)
    after = np.empty_like(first)
    after[:-1] = first[1:]
    after[-1] = size
    ok &= np.add.reduceat(odd, first, dtype=np.intp) - (after - ends) == 1
    hi, lo = _HEXVAL[a[star + 1]], _HEXVAL[a[np.minimum(star + 2, size - 1)]]
    ok &= (hi >= 0) & (lo >= 0)
    bounds = np.empty(2 * len(starts), dtype=np.intp)
    bounds[0::2] = np.where(ok, starts + 1, 0)
    bounds[1::2] = np.where(ok, star, 1)
    xor = np.bitwise_xor.reduceat(a, bounds)[0::2]  # of the bytes between "$" and "*"
    verdict = np.where(ok, np.where(xor != hi * 16 + lo, BAD_SUM, GOOD), OTHER)
    # where the first comma is (of the usual address of 5 characters, 6 bytes after the
    # "$", none before; else one of the 8 bytes after the "$"), and the address's key
    # from the 8 bytes after the "$"
    words = np.ndarray((size - 7,), "<u8", region, 0, (1,))  # the 8 bytes from each
    word = words[np.minimum(starts + 1, size - 8)]
    x = word ^ _COMMAS5  # (a zero byte for each comma among the first 6)
    no_comma = ((x - _ONES5) & ~x & _HIGH5) == 0  # (exact: whether a byte of 5 is zero)
    usual = ((word >> _BITS40) & _BYTE == 44) & no_comma & (n > 9) & (starts + 9 <= size)
    length = np.full(len(starts), 5)
    if not usual.all():
        other = np.flatnonzero(~usual)
        window = a[np.minimum(starts[other, None] + _AFTER, size - 1)]
        commas = window == 44
        first = commas.argmax(axis=1)
        found = commas.any(axis=1) & (first < n[other] - 4) & (first > 0)
        length[other] = np.where(found & (starts[other] + 9 <= size), first, -1)
    keys = (word & _MASK[length]) | (length.astype(np.uint64) << _BITS56)
    return starts, ends, verdict, length, np.where(length > 0, keys.astype(np.int64), -1)


_COMMAS5 = np.uint64(0x2C2C2C2C2C)
_ONES5 = np.uint64(0x0101010101)
_HIGH5 = np.uint64(0x8080808080)
_BYTE = np.uint64(0xFF)
_BITS40 = np.uint64(40)
_AFTER = np.arange(1, 9)
_MASK = np.array([(1 << (8 * k)) - 1 for k in range(8)], dtype=np.uint64)
_BITS56 = np.uint64(56)


def _key(address: str) -> int:
    """An address of 1 to 7 characters as one integer (its bytes and its length), so that
    a run's addresses are looked up without being cut out of the text first."""
    return int.from_bytes(address.encode("ascii"), "little") | len(address) << 56


# A route takes one sentence's fields text to what reads it: route(rest, stamp_ns, out).
Route = Callable[[str, int, list], None]


def _collect(address: str, rest: str, stamp_ns: int, out: list) -> None:
    out.append((address, ",", rest))


def _collector(talker: str, kind: str) -> Route:
    """The route of :meth:`NmeaFramer.feed_raw`: (address, ",", fields) appended to out."""
    return partial(_collect, talker + kind)  # (the address again)


class NmeaFramer:
    """Bytes -> checked sentences (any talker, any type): :meth:`feed` gives
    :class:`Sentence` objects, :meth:`feed_raw` each sentence's address and the text of
    its fields, :meth:`feed_routed` gives that text to a reader chosen by the address."""

    def __init__(self, require_checksum: bool = True, max_line: int = 128) -> None:
        self.require_checksum = require_checksum
        self.max_line = max_line
        self.stats = CodecStats()
        self.overlong = 0
        self.noisy = 0
        self.no_checksum = 0
        self._buf = bytearray()
        self._collectors: dict[str, Route | bool] = {}

    def feed(self, data: bytes) -> list[Sentence]:
        return [
            _sentence(Sentence, (*_address(address), tuple(rest.split(","))))
            for address, _, rest in self.feed_raw(data)
        ]

    def feed_raw(self, data: bytes) -> list[tuple[str, str, str]]:
        """The checked sentences completed by ``data``, each as ``(address, ",", fields)``
        (``"GPGGA"``, the text between the first comma and the ``*``; what
        ``str.partition`` gives)."""
        out: list[tuple[str, str, str]] = []
        self.feed_routed(data, self._collectors, _collector, 0, out)
        return out

    def feed_routed(
        self,
        data: bytes,
        routes: dict[str, Route | bool],
        new_route: Callable[[str, str], Route],
        stamp_ns: int,
        out: list,
    ) -> None:
        """Each checked sentence completed by ``data``, in order, to
        ``routes[address](rest, stamp_ns, out)``; an address not in ``routes`` yet gets
        ``new_route(talker, type)`` (False there marks an address that is none)."""
        buf = self._buf
        if buf:
            buf += data
            end = buf.rfind(b"\n")
            region = bytes(buf[:end]) if end >= 0 else b""
            if end >= 0:
                del buf[: end + 1]
        else:  # (nothing pending: the lines are cut out of data itself, two copies less)
            end = data.rfind(b"\n")
            region = data[:end] if end >= 0 else b""
            buf += data[end + 1 :]
        if end >= 0:
            if region.isascii():
                if len(region) >= _NUMPY_FROM:
                    starts, ends, verdicts, lengths, keys = _classify(region, self.max_line)
                    if not verdicts.any() and lengths.min() > 0:  # (the usual run: all GOOD)
                        self._route_keyed(
                            region.decode("ascii"), (starts + lengths + 2).tolist(),
                            (ends - 3).tolist(), keys.tolist(), routes, new_route, stamp_ns, out,
                        )  # fmt: skip
                    else:
                        self._route(
                            region, starts.tolist(), ends.tolist(), verdicts.tolist(), routes,
                            new_route, stamp_ns, out,
                        )  # fmt: skip
                else:
                    self._route(
                        region, *self._classify_small(region), routes, new_route, stamp_ns, out
                    )
            else:
                for line in region.split(b"\n"):
                    parts = self._line(line)
                    if parts is not None:
                        address = parts[0]
                        route = routes.get(address) or _routed(address, routes, new_route)
                        route(parts[2], stamp_ns, out)  # type: ignore[operator]
        # A pending CR is the end of the line, not part of it: it does not count.
        limit = self.max_line + (buf[-1:] == b"\r")
        if len(buf) > limit:
            # no end of line in sight: keep only from the last '$' if it may still fit
            start = buf.rfind(b"$")
            fits = start >= 0 and len(buf) - start <= limit
            if not fits:
                self.overlong += 1
            cut = start if fits else len(buf)
            self.stats.bytes_skipped += cut
            self.stats.resyncs += 1
            del buf[:cut]

    def _classify_small(self, region: bytes) -> tuple[list[int], ...]:
        """:func:`_classify` without numpy (a short run): one prefix XOR of the run, a
        line's checksum is two look-ups."""
        text = region.decode("ascii")
        prefix = _prefix_xor(region)
        max_line = self.max_line
        starts, ends, verdicts = [], [], []
        pos = 0
        for line in text.split("\n"):
            start = pos
            pos += len(line) + 1
            if line[-1:] == "\r":
                line = line[:-1]
            starts.append(start)
            ends.append(start + len(line))
            star = len(line) - 3
            if (
                line[:1] != "$"
                or star < 1
                or line[star] != "*"
                or len(line) > max_line
                or line.find("$", 1) > 0
                or not line.isprintable()
                or line[star + 1 :] not in _HEX2
            ):
                verdicts.append(OTHER)
            elif prefix[start + star - 1] ^ prefix[start] != _HEX2[line[star + 1 :]]:
                verdicts.append(BAD_SUM)  # the XOR of the bytes between '$' and '*'
            else:
                verdicts.append(GOOD)
        return starts, ends, verdicts

    def _route_keyed(
        self,
        text: str,
        rests: list,
        ends: list,
        keys: list,
        routes: dict,
        new_route: Callable,
        stamp_ns: int,
        out: list,
    ) -> None:
        """A run of good sentences to their routes, each looked up by its address's key
        (the route of an address is kept under its key too); ``text[rests[i]:ends[i]]``
        is a sentence's fields."""
        skipped = bad = 0
        for r, e, key in zip(rests, ends, keys, strict=True):
            try:
                route = routes[key]
            except KeyError:
                address = text[r - 1 - (key >> 56) : r - 1]
                route = routes.get(address)
                if route is None:
                    route = _routed(address, routes, new_route)
                routes[key] = route
            if route:
                route(text[r:e], stamp_ns, out)
            else:
                skipped += e + 3 - (r - 2 - (key >> 56))
                bad += 1
        self.stats.frames_ok += len(keys) - bad
        self.stats.bytes_skipped += skipped

    def _route(
        self,
        region: bytes,
        starts: list,
        ends: list,
        verdicts: list,
        routes: dict,
        new_route: Callable,
        stamp_ns: int,
        out: list,
    ) -> None:
        """The lines of a run by their verdicts: sentences to their routes, counts, or
        :meth:`_line`."""
        text = region.decode("ascii")
        stats = self.stats
        skipped = bad = 0
        good = verdicts.count(GOOD)
        if good == len(verdicts):  # (the usual run: every line a sentence)
            for s, e in zip(starts, ends, strict=True):
                address, _, rest = text[s + 1 : e - 3].partition(",")
                route = routes.get(address)
                if route is None:
                    route = _routed(address, routes, new_route)
                if route:
                    route(rest, stamp_ns, out)
                else:
                    skipped += e - s
                    bad += 1
        else:
            for s, e, verdict in zip(starts, ends, verdicts, strict=True):
                if verdict == GOOD:
                    address, _, rest = text[s + 1 : e - 3].partition(",")
                    route = routes.get(address)
                    if route is None:
                        route = _routed(address, routes, new_route)
                    if route:
                        route(rest, stamp_ns, out)
                    else:
                        skipped += e - s
                        bad += 1
                elif verdict == OTHER:
                    end = region.find(b"\n", s)
                    parts = self._line(region[s : len(region) if end < 0 else end])
                    if parts is not None:
                        route = routes.get(parts[0]) or _routed(parts[0], routes, new_route)
                        route(parts[2], stamp_ns, out)
                else:
                    skipped += e - s
                    stats.bad_checksums += 1
        stats.frames_ok += good - bad
        stats.bytes_skipped += skipped

    def _line(self, line: bytes) -> tuple[str, str, str] | None:
        """Any line: (address, ",", fields) of a sentence in it, or None (counted)."""
        start = line.rfind(b"$")
        if start < 0:
            if line.strip(b"\r"):
                self.stats.bytes_skipped += len(line) + 1
                self.stats.resyncs += 1
            return None
        if start:
            self.stats.bytes_skipped += start
            self.stats.resyncs += 1
        line = line[start:].rstrip(b"\r")
        if len(line) > self.max_line:
            self.overlong += 1
            self.stats.bytes_skipped += len(line)
            return None
        try:
            text = line.decode("ascii")
        except UnicodeDecodeError:
            self.noisy += 1
            self.stats.bytes_skipped += len(line)
            return None
        if not text.isprintable():
            self.noisy += 1
            self.stats.bytes_skipped += len(line)
            return None
        star = text.rfind("*")
        if star >= 0 and len(text) - star == 3 and _HEX.issuperset(line[star + 1 :]):
            body = text[1:star]
            c = 0
            for b in line[1:star]:
                c ^= b
            if c != int(text[star + 1 :], 16):
                self.stats.bad_checksums += 1
                self.stats.bytes_skipped += len(line)
                return None
        elif self.require_checksum:
            self.no_checksum += 1
            self.stats.bytes_skipped += len(line)
            return None
        else:
            body = text[1:]
        parts = body.partition(",")
        if not _address(parts[0]):
            self.stats.bytes_skipped += len(line)
            return None
        self.stats.frames_ok += 1
        return parts


def _routed(address: str, routes: dict, new_route: Callable) -> Route | bool:
    """The route of an address not looked up yet (False: not an address), kept."""
    tk = _address(address)
    route = new_route(*tk) if tk else False
    if len(routes) >= _ADDRESS_CACHE:
        routes.clear()
    routes[address] = route
    return route
