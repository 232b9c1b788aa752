"""IR board codecs: serial bytes or CAN frames -> :class:`msgs.IrScan`.

A good frame of the board whose channel count or resolution differ from the board's
configuration (a short CAN frame can fit a smaller channel count) gives no scan and is
counted in ``stats.malformed``, which the diagnostics publish. Both formats carry a
sequence number, so lost frames are counted (``stats.frames_lost``).
"""

from __future__ import annotations

from operator import itemgetter

from drivers.irboard.canframe import (
    SAMPLE_ID_BASE,
    CanSampleDecoder,
    channels_for_dlc,
    dlc_for,
    max_channels,
    unpack_raw_frame,
    unpacker,
)
from drivers.irboard.convert import IrBoardConfig, IrConverter, make_scan
from drivers.irboard.serialframe import SerialFrameDecoder
from msgs import IrScan


class IrSerialCodec:
    """Serial byte stream of one board -> scans (frames of other boards are skipped)."""

    def __init__(self, config: IrBoardConfig | None = None) -> None:
        self.config = config or IrBoardConfig()
        self.decoder = SerialFrameDecoder()
        self.stats = self.decoder.stats
        self.converter = IrConverter(self.config)

    def feed(self, data: bytes, stamp_ns: int) -> list[IrScan]:
        out: list[IrScan] = []
        for s in self.decoder.feed(data):
            if s.board_id != self.config.board_id:
                continue
            scan = self.converter(s, stamp_ns)
            if scan is None:
                self.stats.malformed += 1
            else:
                out.append(scan)
        return out


class IrCanCodec:
    """CAN frames (arbitration id, data) of one board -> scans.

    A frame of the configured channel count, converted through one curve without a median
    filter (the usual board), is decoded and converted in one pass: the bit field read by
    a function written out for the layout, volts, ranges and statuses read by one
    ``itemgetter`` of the counts from the converter's tables. Every other frame goes
    through the decoder and the converter."""

    def __init__(self, config: IrBoardConfig | None = None) -> None:
        self.config = cfg = config or IrBoardConfig()
        self.decoder = CanSampleDecoder(cfg.board_id, cfg.adc_bits)
        self.stats = self.decoder.stats
        self.converter = IrConverter(cfg)
        self._sample_id = SAMPLE_ID_BASE + cfg.board_id
        self._fast_dlc = -1  # the DLC of the one-pass path (-1: none)
        lists = self.converter.lookup_lists()
        n = cfg.channels
        if lists is not None and 2 <= n <= max_channels(cfg.adc_bits):
            dlc = dlc_for(n, cfg.adc_bits)
            if channels_for_dlc(dlc, cfg.adc_bits) == n:
                self._fast_dlc = dlc
                self._unpack = unpacker(self.decoder.shifts(dlc), (1 << cfg.adc_bits) - 1)
                self._volts, self._ranges, self._status = lists

    def feed_frame(
        self, arb_id: int, data: bytes, stamp_ns: int, is_extended: bool = False
    ) -> IrScan | None:
        if is_extended or arb_id != self._sample_id:
            return None  # someone else's frame on a shared bus: not an error
        if data.__class__ is not bytes:
            data = bytes(data)
        if len(data) != self._fast_dlc:
            return self._feed_other(arb_id, data, stamp_ns)
        v = int.from_bytes(data, "little")
        seq = v & 0xF
        if not self.decoder.accept(seq, data):
            return None
        counts = self._unpack(v)
        get = itemgetter(*counts)
        return make_scan(
            stamp_ns, self.config.board_id, seq, get(self._ranges), get(self._status),
            get(self._volts), counts,
        )  # fmt: skip

    def _feed_other(self, arb_id: int, data: bytes, stamp_ns: int) -> IrScan | None:
        got = self.decoder.feed_counts(arb_id, data)
        if got is None:
            return None
        seq, counts = got
        scan = self.converter.scan_counts(self.config.board_id, seq, counts, stamp_ns)
        if scan is None:
            self.stats.malformed += 1
        return scan

    def feed(self, raw: bytes, stamp_ns: int) -> list[IrScan]:
        """One logged frame (:func:`drivers.irboard.canframe.pack_raw_frame`) -> scans."""
        frame = unpack_raw_frame(raw)
        if frame is None:
            self.stats.malformed += 1
            self.stats.bytes_skipped += len(raw)
            return []
        scan = self.feed_frame(frame[0], frame[1], stamp_ns, frame[2])
        return [] if scan is None else [scan]
