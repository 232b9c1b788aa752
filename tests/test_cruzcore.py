"""CruzCore codec: round trips, unwrapping, resync, commands with their SUM checksum."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from drivers.cruzcore import (
    CommandParser,
    CruzCoreCodec,
    config_command,
    encode_packet,
    parse_command,
    reset_command,
)

D = math.pi / 180


def test_documented_command_checksums():
    assert reset_command() == b"$MIB,RESET*87\r\n"
    assert config_command(115200, 100) == b"$MIA,I,B,115200,R,100,D,Y,N*B9\r\n"
    assert config_command(rate_hz=10) == b"$MIA,,,,R,10,,,*EA\r\n"
    c = parse_command(b"$MIA,,,,R,10,,,*EA\r\n")
    assert c is not None and c.kind == "config" and c.rate_hz == 10 and c.baud is None
    assert parse_command(b"$MIA,,,,R,10,,,*EB\r\n") is None
    assert parse_command(b"$MIB,RESET*87").kind == "reset"


def test_command_parser_skips_garbage():
    p = CommandParser()
    cmds = p.feed(b"\x00\xff$MIB,RES" + b"ET*87\r\n" + b"$MIB,RESET*00\r\n" + reset_command())
    assert [c.kind for c in cmds] == ["reset", "reset"]
    assert p.stats.bad_checksums == 1 and p.stats.bytes_skipped == 2


@settings(max_examples=200, deadline=None)
@given(
    rate=st.floats(-300, 300),
    angle=st.floats(-179.99, 179.99),
)
def test_round_trip(rate, angle):
    c = CruzCoreCodec()
    (s,) = c.feed(encode_packet(rate * D, angle * D), 7)
    assert s.stamp_ns == 7
    assert abs(s.rate_radps - rate * D) <= 0.005 * D + 1e-12
    assert abs(s.angle_wrapped_rad - angle * D) <= 0.005 * D + 1e-12


def test_angle_unwraps_across_180():
    c = CruzCoreCodec()
    angles = [170, 179, -179, -170, 175, 160, 179.99, -179.99, -150]
    # a full turn forward, then back: the unwrapped angle is continuous
    out = []
    for a in angles:
        out += c.feed(encode_packet(0.0, a * D), 0)
    unwrapped = [s.angle_rad / D for s in out]
    for a, b in zip(unwrapped, unwrapped[1:], strict=False):
        assert abs(b - a) < 181
    assert abs(unwrapped[2] - 181) < 0.01
    assert abs(unwrapped[4] - 175) < 0.01  # went back below +180
    assert abs(unwrapped[-1] - 210) < 0.01


@settings(max_examples=150, deadline=None)
@given(
    noise=st.binary(max_size=40),
    cut=st.integers(0, 7),
    angles=st.lists(st.floats(-179, 179), min_size=3, max_size=6),
)
def test_garbage_and_truncation_resync_within_one_frame(noise, cut, angles):
    packets = [encode_packet(0.1, a * D) for a in angles]
    stream = noise + packets[0][:cut] + b"".join(packets[1:])
    c = CruzCoreCodec()
    got = []
    for i in range(0, len(stream), 5):  # any split
        got += c.feed(stream[i : i + 5], 0)
    # The codec is back in step within one frame: the last packet always comes out. A
    # truncated packet plus the next header byte can form a valid frame by coincidence
    # (its checksum's high byte is FF), which then costs at most that one next packet.
    # Angles travel in 0.01 deg steps: compare within one step (a half-step like 0.995
    # may round either way once converted to radians and back).
    want = angles[1:]
    got_angles = [s.angle_wrapped_rad / D for s in got]
    assert abs(got_angles[-1] - want[-1]) <= 0.0101
    assert len(got_angles) >= len(want) - 1


def test_ff_bytes_inside_a_packet_do_not_confuse_the_hunt():
    # rate raw = -1 (FF FF) makes a false header inside the packet
    pkt = encode_packet(-0.01 * D, 10 * D)
    assert pkt[2:4] == b"\xff\xff"
    c = CruzCoreCodec()
    out = c.feed(b"\xff" + pkt + pkt[:3] + pkt, 0)
    assert len(out) == 2 and c.stats.frames_ok == 2
    assert c.stats.bytes_skipped == 4


def test_a_command_that_lost_its_lf_does_not_swallow_the_next():
    cfg = config_command(rate_hz=50)
    for lost in (cfg[:-1], cfg[:-2]):  # LF lost; CR and LF lost
        p = CommandParser()
        cmds = p.feed(lost + reset_command())
        assert [c.kind for c in cmds] == ["config", "reset"] and cmds[0].rate_hz == 50
        assert p.stats.bad_checksums == 0
    p = CommandParser()
    cut = cfg[:10]  # cut short: it is lost, the next one is kept
    assert [c.kind for c in p.feed(cut + reset_command())] == ["reset"]
    assert p.stats.bad_checksums == 1


def test_a_read_of_several_packets_is_stamped_back_one_period_apart():
    """With the gyro's rate, the packets of one read get the times the gyro sent them at
    (the last the read's), never at or before the previous read's last; without it, the
    read's time for all (the packet has no time of its own)."""
    pkts = [encode_packet(0.1, 0.01 * i) for i in range(8)]
    ms = 1_000_000
    c = CruzCoreCodec(rate_hz=100)
    assert [g.stamp_ns for g in c.feed(b"".join(pkts[:5]), 1000 * ms)] == [
        960 * ms, 970 * ms, 980 * ms, 990 * ms, 1000 * ms
    ]  # fmt: skip
    # two packets read only 5 ms later (a stall's end): spread after the last one
    assert [g.stamp_ns for g in c.feed(b"".join(pkts[5:7]), 1005 * ms)] == [1002_500_000, 1005 * ms]
    # a lone packet: the read's time; a clock set back: the read's time for all
    assert [g.stamp_ns for g in c.feed(pkts[7], 1010 * ms)] == [1010 * ms]
    assert {g.stamp_ns for g in c.feed(b"".join(pkts[:3]), 900 * ms)} == {900 * ms}
    # the angles and rates are those of the plain decode, in order
    plain = CruzCoreCodec().feed(b"".join(pkts), 7)
    again = CruzCoreCodec(rate_hz=100).feed(b"".join(pkts), 7 * 10**9)
    assert [(g.rate_radps, g.angle_rad) for g in plain] == [
        (g.rate_radps, g.angle_rad) for g in again
    ]
    assert {g.stamp_ns for g in plain} == {7}
    stamps = [g.stamp_ns for g in again]
    assert stamps == sorted(stamps) and stamps[-1] == 7 * 10**9 and len(set(stamps)) == 8


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.tuples(st.integers(0, 40), st.integers(0, 30_000_000)), min_size=1, max_size=30),
    st.sampled_from([None, 50, 100, 1000]),
)
def test_stamps_of_any_reads_increase_and_never_pass_the_read(reads, rate):
    """Whatever the reads bring (0-40 bytes, cut anywhere) and whenever they come (the
    clock only forward), every sample's stamp is at most its read's, and with a rate
    they strictly increase from read to read unless the reads come closer than a
    nanosecond per packet."""
    stream = b"".join(encode_packet(0.01 * k, 0.001 * k) for k in range(200))
    c = CruzCoreCodec(rate)
    pos, t, prev = 0, 10**9, None
    for size, gap in reads:
        t += gap
        out = c.feed(stream[pos : pos + size], t)
        pos += size
        for g in out:
            assert g.stamp_ns <= t
        stamps = [g.stamp_ns for g in out]
        if rate and out and (prev is None or t - prev >= len(out)):
            assert stamps == sorted(set(stamps))  # strictly increasing within the read
            assert prev is None or stamps[0] > prev
        if out:
            prev = stamps[-1]
