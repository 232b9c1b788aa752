"""hilnav IR ADC board, CAN framing (docs/protocols/irboard.md).

One classic CAN frame (11-bit id) per board per sample:

- arbitration id ``0x300 + board`` (board 0..127) for samples, ``0x280 + board`` for
  commands to the board;
- data = a little-endian bit field: bits 0-3 the sequence number (mod 16), then each
  channel's raw counts (10 or 12 bits) in channel order, LSB first; the DLC is the fewest
  bytes that hold them. 8 bytes hold 6 channels of 10 bits or 5 of 12 bits (4 + 6*10 =
  64); a robot with more sensors uses more boards. The channel count follows from the
  DLC and the board's configured resolution (each count gives a different DLC).
- command SET_RATE: data = ``01 | rate u16 LE``.

CAN checks its own CRC, so the payload has none; the 4-bit sequence still counts lost
frames (gaps of up to 15).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from drivers.base import CodecStats
from drivers.irboard.serialframe import CMD_SET_RATE, RawSample

SAMPLE_ID_BASE = 0x300
COMMAND_ID_BASE = 0x280
MAX_BOARD_ID = 0x7F
SEQ_BITS = 4


def max_channels(adc_bits: int) -> int:
    return (64 - SEQ_BITS) // adc_bits


def dlc_for(channels: int, adc_bits: int) -> int:
    return (SEQ_BITS + channels * adc_bits + 7) // 8


def _channels_for_dlc(dlc: int, adc_bits: int) -> int | None:
    for n in range(1, max_channels(adc_bits) + 1):
        if dlc_for(n, adc_bits) == dlc:
            return n
    return None


# (dlc, adc_bits) -> (channel count, bit offset of each channel); None: no count fits
_LAYOUTS: dict[tuple[int, int], tuple[int, tuple[int, ...]] | None] = {}


def _layout(dlc: int, adc_bits: int) -> tuple[int, tuple[int, ...]] | None:
    key = (dlc, adc_bits)
    if key not in _LAYOUTS:
        n = _channels_for_dlc(dlc, adc_bits)
        _LAYOUTS[key] = None if n is None else (n, tuple(SEQ_BITS + k * adc_bits for k in range(n)))
    return _LAYOUTS[key]


def channels_for_dlc(dlc: int, adc_bits: int) -> int | None:
    layout = _layout(dlc, adc_bits)
    return None if layout is None else layout[0]


def pack_sample(s: RawSample) -> tuple[int, bytes]:
    """(arbitration id, data) of a sample."""
    if not 0 <= s.board_id <= MAX_BOARD_ID:
        raise ValueError(f"CAN board id must be 0..{MAX_BOARD_ID}, not {s.board_id}")
    n = len(s.counts)
    if not 1 <= n <= max_channels(s.adc_bits):
        raise ValueError(
            f"a CAN frame holds 1..{max_channels(s.adc_bits)} channels of {s.adc_bits} bits,"
            f" not {n}: split the sensors over several boards"
        )
    v = s.seq & 0xF
    mask = (1 << s.adc_bits) - 1
    for k, c in enumerate(s.counts):
        v |= (int(c) & mask) << (SEQ_BITS + k * s.adc_bits)
    dlc = dlc_for(n, s.adc_bits)
    return SAMPLE_ID_BASE + s.board_id, v.to_bytes(8, "little")[:dlc]


def unpack_sample(arb_id: int, data: bytes, adc_bits: int) -> RawSample | None:
    """Sample of a frame, None if the id is not a sample id or the DLC fits no channel count."""
    board = arb_id - SAMPLE_ID_BASE
    if not 0 <= board <= MAX_BOARD_ID:
        return None
    layout = _layout(len(data), adc_bits)
    if layout is None:
        return None
    v = int.from_bytes(data, "little")
    mask = (1 << adc_bits) - 1
    counts = tuple([(v >> shift) & mask for shift in layout[1]])
    return RawSample(board, v & 0xF, adc_bits, counts)


def pack_set_rate(board_id: int, rate_hz: int) -> tuple[int, bytes]:
    if not 1 <= rate_hz <= 1000:
        raise ValueError(f"IR board sample rate must be 1..1000 Hz, not {rate_hz}")
    return COMMAND_ID_BASE + board_id, bytes((CMD_SET_RATE,)) + int(rate_hz).to_bytes(2, "little")


def unpack_command(arb_id: int, data: bytes) -> tuple[int, int] | None:
    """(board, rate_hz) of a SET_RATE command frame, else None."""
    board = arb_id - COMMAND_ID_BASE
    if not 0 <= board <= MAX_BOARD_ID or len(data) != 3 or data[0] != CMD_SET_RATE:
        return None
    return board, int.from_bytes(data[1:3], "little")


@dataclass
class CanSampleDecoder:
    """Frames -> :class:`RawSample` for one board; foreign or malformed frames are counted.

    The 4-bit sequence counts lost frames: a gap of k means k frames lost (mod 16, so 16
    lost in a row go unseen). A frame equal to the previous one (same sequence number, same
    data: a retransmission seen twice) is a duplicate, counted and dropped, not 15 lost.
    """

    board_id: int
    adc_bits: int = 10

    def __post_init__(self) -> None:
        self.stats = CodecStats()
        self._last_seq = -1  # the previous frame's sequence number and data (-1: none yet)
        self._last_data = b""
        self._sample_id = SAMPLE_ID_BASE + self.board_id
        self._mask = (1 << self.adc_bits) - 1
        # data length -> bit offsets of the channels (None: no channel count fits)
        self._shifts = {
            dlc: None if (lay := _layout(dlc, self.adc_bits)) is None else lay[1]
            for dlc in range(9)
        }

    def shifts(self, dlc: int) -> tuple[int, ...] | None:
        """Bit offsets of the channels of a frame of ``dlc`` bytes (None: no count fits)."""
        return self._shifts.get(dlc)

    def feed_frame(self, arb_id: int, data: bytes, is_extended: bool = False) -> RawSample | None:
        got = self.feed_counts(arb_id, data, is_extended)
        return None if got is None else RawSample(self.board_id, got[0], self.adc_bits, got[1])

    def feed_counts(
        self, arb_id: int, data: bytes, is_extended: bool = False
    ) -> tuple[int, tuple[int, ...]] | None:
        """:meth:`feed_frame` as (sequence number, counts), without the RawSample."""
        if is_extended or arb_id != self._sample_id:
            return None  # someone else's frame on a shared bus: not an error
        if data.__class__ is not bytes:
            data = bytes(data)
        shifts = self._shifts.get(len(data))
        if shifts is None:
            self.stats.bytes_skipped += len(data)
            self.stats.bad_checksums += 1
            return None
        v = int.from_bytes(data, "little")
        seq = v & 0xF
        if not self.accept(seq, data):
            return None
        mask = self._mask
        return seq, tuple([(v >> shift) & mask for shift in shifts])

    def accept(self, seq: int, data: bytes) -> bool:
        """The sequence bookkeeping of a well-formed frame of this board: False for a
        duplicate (counted), else the frames lost before it counted and True."""
        last = self._last_seq
        if last >= 0:
            if last == seq and self._last_data == data:
                self.stats.duplicates += 1
                return False
            self.stats.frames_lost += (seq - last - 1) & 0xF
        self._last_seq = seq
        self._last_data = data
        self.stats.frames_ok += 1
        return True


def unpacker(shifts: tuple[int, ...], mask: int) -> Callable[[int], tuple[int, ...]]:
    """``f(v) == tuple((v >> s) & mask for s in shifts)``, written out for the layout (a
    generated function of integer constants: no loop per frame)."""
    items = "".join(f"v >> {int(s)} & {int(mask)}, " for s in shifts)
    return eval(f"lambda v: ({items})")  # integers only


# A CAN frame as logged (msgs.RawBytes of the IR device on CAN): the arbitration id as 4
# big-endian bytes, with bit 31 set for an extended id (SocketCAN's CAN_EFF_FLAG), then
# the data bytes.
EFF_FLAG = 0x8000_0000


def pack_raw_frame(arb_id: int, data: bytes, is_extended: bool = False) -> bytes:
    word = arb_id | (EFF_FLAG if is_extended else 0)
    return word.to_bytes(4, "big") + bytes(data)


def unpack_raw_frame(raw: bytes) -> tuple[int, bytes, bool] | None:
    """(arbitration id, data, extended) of a logged frame; None if it is too short.
    Logs written before the flag existed mark nothing: an id over 11 bits is extended."""
    if len(raw) < 4 or len(raw) > 4 + 64:
        return None
    word = int.from_bytes(raw[:4], "big")
    arb = word & 0x1FFF_FFFF
    return arb, bytes(raw[4:]), bool(word & EFF_FLAG) or arb > 0x7FF
