"""IR ADC board: serial and CAN framing round trips, resync, conversion to flagged ranges."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

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
