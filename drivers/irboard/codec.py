"""IR board codecs: serial bytes or CAN frames -> :class:`msgs.IrScan`.

A good frame of the board whose channel count or resolution differ from the board's
configuration (a short CAN frame can fit a smaller channel count) gives no scan and is
counted in ``stats.malformed``, which the diagnostics publish. Both formats carry a
sequence number, so lost frames are counted (``stats.frames_lost``).
"""

from __future__ import annotations

from drivers.irboard.canframe import CanSampleDecoder, unpack_raw_frame
from drivers.irboard.convert import IrBoardConfig, IrConverter
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
    """CAN frames (arbitration id, data) of one board -> scans."""

    def __init__(self, config: IrBoardConfig | None = None) -> None:
        self.config = config or IrBoardConfig()
        self.decoder = CanSampleDecoder(self.config.board_id, self.config.adc_bits)
        self.stats = self.decoder.stats
        self.converter = IrConverter(self.config)

    def feed_frame(
        self, arb_id: int, data: bytes, stamp_ns: int, is_extended: bool = False
    ) -> IrScan | None:
        got = self.decoder.feed_counts(arb_id, data, is_extended)
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
