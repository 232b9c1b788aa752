import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.arcos import ArcosCodec, Cmd, PacketParser, checksum, encode_command, frame, unwrap15
from drivers.arcos.commands import decode_argument, split_vel2, vel2_argument
from drivers.arcos.packets import (
    decode_config,
    decode_sip,
    decode_sync2,
    encode_config,
    encode_sip,
    encode_sync2,
)
from drivers.arcos.params import P3DX
from msgs import RobotInfo, RobotOdometry


def test_checksum_vectors_from_the_notes():
    assert encode_command(Cmd.PULSE) == bytes.fromhex("FAFB03000000")
    assert encode_command(Cmd.OPEN, 1) == bytes.fromhex("FAFB06013B0100023B")
    assert encode_command(Cmd.VEL, -200) == bytes.fromhex("FAFB060B1BC800D31B")


def test_checksum_odd_length_xors_last_byte():
    assert checksum(b"\x01\x02\x03") == (0x0102 ^ 0x03)
    assert checksum(b"\xff\xff\xff\xff") == 0xFFFE


@given(st.integers(0, 255), st.binary(max_size=200))
def test_frame_round_trip(pid, data):
    pkts = PacketParser().feed(frame(pid, data), 0)
    assert [(p.packet_id, p.data) for p in pkts] == [(pid, data)]


@given(st.one_of(st.integers(-0xFFFF, 0xFFFF), st.binary(max_size=50)))
def test_argument_round_trip(arg):
    pkt = PacketParser().feed(encode_command(Cmd.VEL, arg), 0)[0]
    assert decode_argument(pkt.data) == arg


@given(st.integers(-2540, 2540), st.integers(-2540, 2540))
def test_vel2_round_trip(left, right):
    lq, rq = split_vel2(vel2_argument(left, right))
    assert abs(lq - left) <= 10 and abs(rq - right) <= 10


def _sip_fields(**kw):
    f = dict(XPOS=100, YPOS=200, THPOS=1024, L_VEL=-100, R_VEL=150, BATTERY=125,
             STALL_AND_BUMPERS=0x0301, CONTROL=0, FLAGS=0x21, COMPASS=0)  # fmt: skip
    f.update(kw)
    return f


def test_sip_all_fields_and_optional_trailers():
    fields = _sip_fields(BATTERYX10=128, ROTVEL=-55, FAULTFLAGS=7)
    raw = decode_sip(encode_sip(fields, {0: 500, 3: 1200}))
    assert raw["SONAR_0"] == 500 and raw["SONAR_3"] == 1200 and raw["SONAR_COUNT"] == 2
    assert raw["ROTVEL"] == -55 and raw["FAULTFLAGS"] == 7 and raw["BATTERYX10"] == 128
    short = decode_sip(encode_sip(_sip_fields()))
    assert "GRIP_STATE" not in short and short["THPOS"] == 1024


def _sip_packet(pid=0x33, **kw):
    return frame(pid, encode_sip(_sip_fields(**kw)))


def test_codec_sip_to_odometry_units_and_flags():
    c = ArcosCodec()
    (m0,) = c.feed(_sip_packet(ROTVEL=100), 1)
    assert isinstance(m0, RobotOdometry) and m0.pose.x == 0.0  # the first SIP sets the reference
    (m1,) = c.feed(_sip_packet(XPOS=1100, YPOS=150, THPOS=2048, ROTVEL=100), 2)
    assert m1.pose.x == pytest.approx(1.0) and m1.pose.y == pytest.approx(-0.05)
    assert m1.pose.theta == pytest.approx(1024 * 0.001534)
    assert m1.left_vel_mps == -0.1 and m1.right_vel_mps == 0.15
    assert m1.angular_vel_radps == pytest.approx(math.radians(10.0))
    assert m1.motors_enabled and m1.estop and m1.moving
    assert m1.left_stall and m1.right_stall and m1.front_bumpers == 1
    assert m1.raw["XPOS"] == 1100


def test_p3dx_distance_factor():
    c = ArcosCodec(P3DX)
    c.feed(_sip_packet(XPOS=0), 0)
    (m,) = c.feed(_sip_packet(XPOS=1000), 1)
    assert m.pose.x == pytest.approx(0.485)


@pytest.mark.parametrize(
    "prev,new,delta",
    [(0x7FF0, 0x0010, 0x20), (0x0010, 0x7FF0, -0x20), (100, 300, 200), (0x8005, 0x0010, 11)],
)
def test_unwrap15(prev, new, delta):
    assert unwrap15(prev, new) == delta


def test_position_wraps_across_0x7fff_continuously():
    c = ArcosCodec()
    xs = []
    raw = 0x7E00
    for _ in range(10):
        xs += [m.pose.x for m in c.feed(_sip_packet(XPOS=raw & 0x7FFF), 0)]
        raw += 0x100
    assert xs == pytest.approx([i * 0.256 for i in range(10)])


def test_heading_difference_wraps():
    c = ArcosCodec()
    c.feed(_sip_packet(THPOS=2040), 0)
    (m,) = c.feed(_sip_packet(THPOS=-2040), 1)
    assert m.pose.theta == pytest.approx(-4080 * 0.001534 + 2 * math.pi)
    assert abs(m.pose.theta) < 0.03


def test_config_round_trip_and_short_packet():
    values = {"Type": "Pioneer", "SubType": "p3dx-sh", "Name": "bob", "Watchdog": 2000, "TicksMM": 128,
              "FirmwareVersion": "x", "DriftFactor": -3}  # fmt: skip
    data = encode_config(values)
    got = decode_config(data)
    assert {k: got[k] for k in values} == values
    partial = decode_config(data[:30])
    assert partial["Type"] == "Pioneer" and "Watchdog" not in partial
    (info,) = ArcosCodec().feed(frame(0x20, data), 5)
    assert isinstance(info, RobotInfo) and info.name == "bob" and info.subclass == "p3dx-sh"


def test_sync2_strings():
    assert decode_sync2(encode_sync2("a", "Pioneer", "p3dx")) == ("a", "Pioneer", "p3dx")
    assert decode_sync2(b"only") == ("only", "", "")


def test_encoder_packet_attaches_to_next_sip():
    c = ArcosCodec()
    assert c.feed(frame(0x90, struct.pack("<ii", -5, 70000)), 0) == []
    (m,) = c.feed(_sip_packet(), 1)
    assert (m.left_encoder, m.right_encoder) == (-5, 70000)


def test_junk_before_sync_and_between_packets_is_skipped():
    c = ArcosCodec()
    msgs = c.feed(b"WMS2\r" + _sip_packet() + b"\x00\xfa\x12" + _sip_packet(XPOS=110), 0)
    assert len(msgs) == 2 and msgs[1].pose.x == pytest.approx(0.01)
    assert c.stats.bytes_skipped == 8 and c.stats.frames_ok == 2


def test_bad_checksum_dropped_and_next_frame_decoded():
    bad = bytearray(_sip_packet())
    bad[-1] ^= 0xFF
    c = ArcosCodec()
    msgs = c.feed(bytes(bad) + _sip_packet(), 0)
    assert len(msgs) == 1 and c.stats.bad_checksums == 1


def test_short_sip_is_counted_not_raised():
    c = ArcosCodec()
    assert c.feed(frame(0x32, b"\x01\x02\x03"), 0) == []
    assert c.stats.malformed == 1


def test_stale_partial_packet_is_dropped_after_100ms():
    c = ArcosCodec()
    pkt = _sip_packet()
    assert c.feed(pkt[:10], 0) == []
    assert len(c.feed(pkt, 200_000_000)) == 1
    assert c.stats.bytes_skipped == 10


@settings(max_examples=200)
@given(st.binary(max_size=400), st.lists(st.integers(0, 400), max_size=5))
def test_garbage_never_crashes_and_resyncs(noise, cuts):
    c = ArcosCodec()
    c.feed(noise, 0)
    stream = _sip_packet() + _sip_packet(XPOS=120)
    pos = 0
    got = []
    for cut in sorted(set(cuts)) + [len(stream)]:
        got += c.feed(stream[pos:cut], 0)
        pos = max(pos, cut)
    # Garbage may swallow at most the first packet (a stray FA FB may claim its bytes).
    assert 1 <= len([m for m in got if isinstance(m, RobotOdometry)]) <= 2


def test_moving_comes_from_the_velocities_when_every_sip_says_stopped():
    """AMRISim sends every SIP as type 0x32; the Pioneer sends 0x33 while moving."""
    from drivers.arcos import ArcosCodec, frame
    from drivers.arcos.packets import SIP_MOVING, SIP_STOPPED, encode_sip

    base = {"XPOS": 100, "YPOS": 200, "THPOS": 5, "BATTERY": 128, "FLAGS": 1,
            "BATTERYX10": 128, "FAULTFLAGS": 0}  # fmt: skip
    stream = [
        frame(SIP_STOPPED, encode_sip({**base, "L_VEL": 100, "R_VEL": 120, "ROTVEL": 10})),
        frame(SIP_STOPPED, encode_sip({**base, "L_VEL": 0, "R_VEL": 0, "ROTVEL": 5})),
        frame(SIP_STOPPED, encode_sip({**base, "L_VEL": 0, "R_VEL": 0, "ROTVEL": 0})),
        frame(SIP_MOVING, encode_sip({**base, "L_VEL": 0, "R_VEL": 0, "ROTVEL": 0})),
    ]
    codec = ArcosCodec()
    got = [m.moving for m in codec.feed(b"".join(stream), 1) if hasattr(m, "moving")]
    assert got == [True, True, False, True]


def test_corrupted_count_does_not_hold_back_the_next_packets():
    """COUNT 0xF0 claims 243 bytes; each following SIP is returned by the feed completing it."""
    bad = bytearray(_sip_packet())
    bad[2] = 0xF0
    c = ArcosCodec()
    assert c.feed(bytes(bad), 0) == []
    for k in range(3):
        (m,) = c.feed(_sip_packet(XPOS=110 + k), 10_000_000 * (k + 1))
        assert m.stamp_ns == 10_000_000 * (k + 1)
    assert c.stats.resyncs == 1 and c.stats.bytes_skipped == len(bad)
    assert c.stats.frames_ok == 3 and c.stats.frames_lost == 0  # ARCOS cannot count losses
