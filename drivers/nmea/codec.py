"""NMEA byte stream -> :class:`msgs.GpsFix` per epoch and :class:`msgs.GpsSky`.

The framer (:mod:`drivers.nmea.framer`) checks the sentences: overlong lines, binary
noise and wrong checksums are dropped and counted, and a sentence cut short by the next
one is dropped with the framer back in step within one sentence. Each checked sentence is
read by the reader of its address (``GPGGA``: the talker and the type), and the readers
apply gpsd's rules (:mod:`drivers.nmea.epoch`, :mod:`drivers.nmea.session`). A sentence of
a decoded type with fewer fields than gpsd accepts, or a date out of range, is counted in
``stats.malformed``. NMEA has no sequence numbers: a lost sentence cannot be counted.
"""

from __future__ import annotations

from drivers.nmea.epoch import EpochCombiner
from drivers.nmea.fastfix import FAST
from drivers.nmea.fastpath import bind, reference
from drivers.nmea.framer import NmeaFramer, Route
from drivers.nmea.local import Datum
from drivers.nmea.session import HANDLERS
from msgs import GpsFix, GpsSky

__all__ = ["NmeaCodec", "NmeaFramer"]


class NmeaCodec:
    """Bytes -> :class:`msgs.GpsFix` per epoch and :class:`msgs.GpsSky` when the sky
    changed (see :mod:`drivers.nmea.epoch`).

    Each sentence is routed by its address (``GPGGA``, looked up once per address): the
    ordinary sentences of the common types take :mod:`drivers.nmea.fastpath`, any other
    the reference path (:meth:`EpochCombiner.add_into`); ``fast=False`` sends every
    sentence the reference way (the tests compare the two). A framer whose ``feed`` is
    overridden (one that watches the sentences) is read through its ``feed``."""

    def __init__(
        self,
        require_checksum: bool = True,
        max_line: int = 128,
        datum: Datum | None = None,
        rollover_before_year: int | None = None,
        fast: bool = True,
    ) -> None:
        self.framer = NmeaFramer(require_checksum, max_line)
        self.combiner = EpochCombiner(datum, rollover_before_year)
        self.stats = self.framer.stats
        self.ignored = 0  # well-formed sentences of types not decoded (TXT, ...)
        self._fast = FAST if fast else {}
        self._routes: dict[str, Route | bool] = {}  # address -> reader

    @property
    def malformed(self) -> int:
        """Sentences of decoded types whose fields do not parse (``stats.malformed``)."""
        return self.stats.malformed

    def _route(self, talker: str, kind: str) -> Route:
        """What reads a sentence of this talker and type: ``route(rest, stamp_ns, out)``."""
        if talker == "P":
            kind = "P" + kind
        elif kind in self._fast:
            return bind(self._fast[kind], self.combiner, talker)
        if kind in HANDLERS:
            return bind(reference, self.combiner, talker, kind)
        return self._ignore

    def _ignore(self, rest: str, stamp_ns: int, out: list) -> None:
        self.ignored += 1

    def feed(self, data: bytes, stamp_ns: int) -> list[GpsFix | GpsSky]:
        out: list[GpsFix | GpsSky] = []
        session = self.combiner.session
        before = session.malformed
        framer = self.framer
        if type(framer).feed is NmeaFramer.feed:
            framer.feed_routed(data, self._routes, self._route, stamp_ns, out)
        else:
            for talker, kind, fields in framer.feed(data):
                self._route(talker, kind)(",".join(fields), stamp_ns, out)
        self.stats.malformed += session.malformed - before
        return out

    def flush(self) -> list[GpsFix | GpsSky]:
        """The last epoch's fix (and sky) at the end of a stream."""
        return self.combiner.flush()
