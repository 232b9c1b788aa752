"""NMEA 0183 GPS: sentences, gpsd's rules for combining them into :class:`msgs.GpsFix` and
:class:`msgs.GpsSky`, local metres."""

from drivers.nmea.codec import NmeaCodec, NmeaFramer
from drivers.nmea.epoch import ROLLOVER_S, EpochCombiner
from drivers.nmea.local import Datum
from drivers.nmea.memo import clear_caches
from drivers.nmea.sentences import Sentence, build, xor_checksum

__all__ = [
    "ROLLOVER_S",
    "Datum",
    "EpochCombiner",
    "NmeaCodec",
    "NmeaFramer",
    "Sentence",
    "build",
    "clear_caches",
    "xor_checksum",
]
