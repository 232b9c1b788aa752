"""IR ADC board: serial and CAN framing round trips, resync, conversion to flagged ranges."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.base import LinkDiagnostics
from drivers.irboard import (
    IrBoardConfig,
    IrCanCodec,
    IrSerialCodec,
    RawSample,
    SerialFrameDecoder,
    crc16_ccitt,
    encode_sample,
    pack_sample,
    pack_set_rate,
    set_rate_command,
    unpack_command,
    unpack_sample,
    volts_to_counts,
)
from drivers.irboard.canframe import dlc_for, max_channels
from drivers.sharp import SharpCurve


@st.composite
def samples(draw, max_ch=8):
    bits = draw(st.sampled_from([10, 12]))
    n = draw(st.integers(1, max_ch if max_ch else max_channels(bits)))
    if not max_ch:
        n = min(n, max_channels(bits))
    counts = draw(st.lists(st.integers(0, (1 << bits) - 1), min_size=n, max_size=n))
    return RawSample(draw(st.integers(0, 127)), draw(st.integers(0, 0xFFFF)), bits, tuple(counts))


def test_crc_check_value():
    assert crc16_ccitt(b"123456789") == 0x29B1  # CRC-16/CCITT-FALSE


@settings(max_examples=200, deadline=None)
@given(samples())
def test_serial_round_trip(s):
    d = SerialFrameDecoder()
    assert d.feed(encode_sample(s)) == [s]


@settings(max_examples=200, deadline=None)
@given(samples(max_ch=0))
def test_can_round_trip(s):
    arb, data = pack_sample(s)
    assert len(data) == dlc_for(len(s.counts), s.adc_bits) <= 8
    back = unpack_sample(arb, data, s.adc_bits)
    assert back == RawSample(s.board_id, s.seq & 0xF, s.adc_bits, s.counts)


def test_can_capacity_and_commands():
    assert max_channels(10) == 6 and max_channels(12) == 5
    with pytest.raises(ValueError, match="several boards"):
        pack_sample(RawSample(1, 0, 12, (1,) * 6))
    assert unpack_command(*pack_set_rate(3, 50)) == (3, 50)
    d = SerialFrameDecoder(commands=True)
    (cmd,) = d.feed(b"\x00" + set_rate_command(3, 50))
    assert cmd.board_id == 3 and cmd.rate_hz == 50


@settings(max_examples=150, deadline=None)
@given(noise=st.binary(max_size=60), cut=st.integers(0, 24), chunk=st.integers(1, 30))
def test_serial_corruption_resyncs_within_one_frame(noise, cut, chunk):
    frames = [RawSample(1, k, 10, tuple(range(k, k + 6))) for k in range(4)]
    raw = [encode_sample(f) for f in frames]
    stream = noise + raw[0][:cut] + b"".join(raw[1:])
    d = SerialFrameDecoder()
    got = []
    for i in range(0, len(stream), chunk):
        got += d.feed(stream[i : i + chunk])
    assert got[-3:] == frames[1:]


def test_lost_frames_are_counted():
    d = SerialFrameDecoder()
    d.feed(b"".join(encode_sample(RawSample(1, k, 10, (5,))) for k in (1, 2, 5, 6)))
    assert d.stats.frames_lost == 2 and d.stats.frames_ok == 4
    bad = bytearray(encode_sample(RawSample(1, 7, 10, (5,))))
    bad[-1] ^= 1
    d.feed(bytes(bad))
    assert d.stats.bad_checksums == 1


def test_conversion_flags_rather_than_clamps():
    cfg = IrBoardConfig(mounts=((0, 0, 0),) * 5, adc_bits=12)
    curve = SharpCurve()
    true = np.array([0.7, 2.0, 4.0, np.inf, 7.0])
    counts = volts_to_counts(curve.voltage(true), 12, cfg.vref_v)
    counts[0] = volts_to_counts(np.array([2.6]), 12, 5.0)[0]  # reads ~0.9 m: too near
    codec = IrSerialCodec(cfg)
    (scan,) = codec.feed(encode_sample(RawSample(1, 0, 12, tuple(int(c) for c in counts))), 5)
    assert scan.status == ("too_near", "ok", "ok", "no_return", "too_far")
    assert abs(scan.ranges_m[1] - 2.0) < 0.02 and abs(scan.ranges_m[2] - 4.0) < 0.1
    assert np.isnan(scan.ranges_m[3])


def test_near_obstacle_reads_far():
    curve = SharpCurve()
    (v,) = curve.voltage(np.array([0.2]))
    r, status = curve.range(np.array([v]))
    assert r[0] > 1.5 and status[0] in (0, 2)  # the near-range ambiguity


def test_calibration_table_and_median():
    table = SharpCurve((1.0, 2.0, 3.0), (2.0, 1.6, 1.4))
    cfg = IrBoardConfig(
        mounts=((0, 0, 0), (0, 0, 1)), curves=(table, SharpCurve()), median_window=3
    )
    codec = IrSerialCodec(cfg)
    c16 = int(volts_to_counts(np.array([1.6]), 10, 5.0)[0])
    scans = []
    for k, spike in enumerate([c16, c16, 50, c16]):
        scans += codec.feed(encode_sample(RawSample(1, k, 10, (c16, spike))), k)
    assert abs(scans[0].ranges_m[0] - 2.0) < 0.05  # the calibration table, not the datasheet
    assert 2.6 < scans[0].ranges_m[1] < 2.9  # 1.6 V on the datasheet curve
    assert scans[2].status[1] == "ok" and scans[2].ranges_m[1] == scans[0].ranges_m[1]
    with pytest.raises(ValueError, match="ir.curves"):
        IrBoardConfig(mounts=((0, 0, 0),), curves=(table, table))


def test_can_codec_ignores_foreign_frames_and_counts_bad_dlc():
    codec = IrCanCodec(IrBoardConfig(board_id=2))
    arb, data = pack_sample(RawSample(2, 3, 10, (600,) * 6))
    assert codec.feed_frame(0x123, b"\x00", 1) is None and codec.stats.frames_ok == 0
    scan = codec.feed_frame(arb, data, 1)
    assert scan is not None and scan.seq == 3 and len(scan.ranges_m) == 6
    assert codec.feed_frame(arb, data[:4], 2) is None and codec.stats.bad_checksums == 1


def test_a_command_split_across_reads_is_decoded_once_whole():
    """A SET_RATE command arriving in pieces is decoded when its last byte arrives."""
    cmd = set_rate_command(1, 50)
    for cut in range(1, len(cmd)):
        d = SerialFrameDecoder(commands=True)
        assert d.feed(cmd[:cut]) == []
        (got,) = d.feed(cmd[cut:])
        assert got.rate_hz == 50 and d.stats.bad_checksums == 0 and d.stats.bytes_skipped == 0


def test_a_bogus_header_does_not_hold_back_the_frame_inside_it():
    """A corrupted channel count (8 instead of 1) is skipped as soon as a good frame is whole."""
    good = [encode_sample(RawSample(1, k, 10, (5,))) for k in range(2)]
    bad = bytearray(good[0])
    bad[5] = 8  # announces 25 bytes; the next 11-byte frame is complete first
    d = SerialFrameDecoder()
    got = d.feed(bytes(bad) + good[1])
    assert [s.seq for s in got] == [1] and d.stats.resyncs == 1


def test_duplicated_frames_are_counted_not_lost():
    frames = [encode_sample(RawSample(1, k, 10, (5 + k,))) for k in (1, 2, 2, 3)]
    d = SerialFrameDecoder()
    assert [s.seq for s in d.feed(b"".join(frames))] == [1, 2, 3]
    assert d.stats.duplicates == 1 and d.stats.frames_lost == 0 and d.stats.frames_ok == 3
    arb, data = pack_sample(RawSample(2, 7, 10, (600,) * 6))
    _, data8 = pack_sample(RawSample(2, 8, 10, (600,) * 6))
    codec = IrCanCodec(IrBoardConfig(board_id=2))
    scans = [codec.feed_frame(arb, x, 0) for x in (data, data, data8)]
    assert [s is not None for s in scans] == [True, False, True]
    assert codec.stats.duplicates == 1 and codec.stats.frames_lost == 0


def test_lost_can_frames_are_counted_from_the_4_bit_sequence():
    codec = IrCanCodec(IrBoardConfig(board_id=2))
    for seq in (14, 15, 2, 3):  # 0 and 1 lost across the wrap
        codec.feed_frame(*pack_sample(RawSample(2, seq, 10, (600 + seq,) * 6)), 0)
    assert codec.stats.frames_lost == 2 and codec.stats.frames_ok == 4
    # the same sequence number with other data: a whole turn of the counter, 15 lost
    codec.feed_frame(*pack_sample(RawSample(2, 3, 10, (700,) * 6)), 0)
    assert codec.stats.frames_lost == 17 and codec.stats.duplicates == 0


def test_a_short_frame_of_another_channel_count_is_counted_malformed():
    """A DLC-7 frame fits 5 channels of 10 bits: a good frame, but not this 6-channel board's."""
    codec = IrCanCodec(IrBoardConfig(board_id=2))
    arb, data = pack_sample(RawSample(2, 3, 10, (600,) * 6))
    assert codec.feed_frame(arb, data[:7], 0) is None
    assert codec.stats.malformed == 1
    serial = IrSerialCodec(IrBoardConfig(board_id=1))
    assert serial.feed(encode_sample(RawSample(1, 0, 10, (600,) * 5)), 0) == []
    assert serial.stats.malformed == 1
    can = IrCanCodec()
    assert can.feed(b"\x00\x03", 0) == [] and can.stats.malformed == 1  # a cut logged frame


class _Link(LinkDiagnostics):
    device, connected, reconnects, last_error, _last_seen_ns = "ir", True, 0, "", 0

    def __init__(self, codec: IrCanCodec) -> None:
        self.codec = codec


def test_diagnostics_show_malformed_and_duplicate_frames():
    codec = IrCanCodec(IrBoardConfig(board_id=2))
    arb, data = pack_sample(RawSample(2, 3, 10, (600,) * 6))
    _, data4 = pack_sample(RawSample(2, 4, 10, (600,) * 6))
    for frame in (data, data, data4[:7]):
        codec.feed_frame(arb, frame, 0)
    diag = _Link(codec).diagnostics(0)
    assert (diag.frames_ok, diag.duplicates, diag.malformed, diag.frames_lost) == (2, 1, 1, 0)


@settings(max_examples=100, deadline=None)
@given(st.data())
def test_can_one_pass_path_equals_the_numpy_conversion(data):
    """The CAN codec's one-pass decode + table look-up gives the scan of the per-sample
    numpy path (IrConverter._convert), whatever the channel count and resolution."""
    bits = data.draw(st.sampled_from([10, 12]))
    n = data.draw(st.integers(1, min(8, max_channels(bits))))
    cfg = IrBoardConfig(board_id=3, adc_bits=bits, mounts=((0.0, 0.0, 0.0),) * n)
    codec = IrCanCodec(cfg)
    counts = data.draw(st.lists(st.integers(0, (1 << bits) - 1), min_size=n, max_size=n))
    sample = RawSample(3, data.draw(st.integers(0, 15)), bits, tuple(counts))
    scan = codec.feed_frame(*pack_sample(sample), 7)
    assert repr(scan) == repr(codec.converter._convert(sample, 7))  # nan == nan, exactly
    assert type(scan.raw_counts[0]) is int and codec.stats.frames_ok == 1


def test_can_frames_of_boards_with_several_curves_or_a_median_take_the_general_path():
    table = SharpCurve((1.0, 2.0, 3.0), (2.0, 1.6, 1.4))
    for cfg in (
        IrBoardConfig(board_id=2, mounts=((0, 0, 0), (0, 0, 1)), curves=(table, SharpCurve())),
        IrBoardConfig(board_id=2, mounts=((0, 0, 0), (0, 0, 1)), median_window=3),
    ):
        codec = IrCanCodec(cfg)
        sample = RawSample(2, 5, 10, (300, 400))
        scan = codec.feed_frame(*pack_sample(sample), 1)
        assert repr(scan) == repr(IrCanCodec(cfg).converter(sample, 1))
