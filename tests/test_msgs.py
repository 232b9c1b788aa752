import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from msgs import (
    DecodeError,
    GpsFix,
    Interval,
    IrScan,
    Pose2D,
    PoseBox,
    RobotOdometry,
    decode,
    encode,
    json_schema,
    schema_name,
    wrap_angle,
)


def odom(**kw):
    base = dict(
        stamp_ns=123,
        pose=Pose2D(1.0, -2.0, 0.5),
        left_vel_mps=0.1,
        right_vel_mps=0.2,
        linear_vel_mps=0.15,
        angular_vel_radps=0.3,
        battery_v=12.5,
        moving=True,
        motors_enabled=True,
        raw={"XPOS": 1000},
    )
    base.update(kw)
    return RobotOdometry(**base)


def test_round_trip_nested_and_optional():
    msg = odom(left_encoder=5)
    assert decode(RobotOdometry, encode(msg)) == msg
    fix = GpsFix(stamp_ns=1, lat_deg=48.1, lon_deg=11.5, mode=3, hdop=float("inf"))
    back = decode(GpsFix, encode(fix))
    assert back.lat_deg == 48.1 and math.isinf(back.hdop)
    box = PoseBox(1, "r1", Interval(0, 1), Interval(2, 4), Interval(-0.1, 0.1))
    assert decode(PoseBox, encode(box)).area_m2 == pytest.approx(2.0)


@given(st.floats(allow_nan=False, allow_infinity=False), st.integers(0, 2**62))
def test_round_trip_property(x, stamp):
    msg = IrScan(stamp, 1, 2, (x, 1.0), ("ok", "too_far"), (2.5, 1.4), (512, 300))
    assert decode(IrScan, encode(msg)) == msg


@pytest.mark.parametrize(
    "payload",
    [b"", b"\xff\xfe", b"[]", b'{"stamp_ns": "x"}', b'{"stamp_ns": 1}', b"null", b'{"a":'],
)
def test_malformed_payloads_raise_decode_error(payload):
    with pytest.raises(DecodeError):
        decode(RobotOdometry, payload)


def test_bool_is_not_an_int():
    payload = b'{"stamp_ns":true,"board_id":1,"seq":1,"ranges_m":[],"status":[],"voltages_v":[]}'
    with pytest.raises(DecodeError, match="stamp_ns"):
        decode(IrScan, payload)


def test_schema_lists_fields():
    schema = json_schema(RobotOdometry)
    assert schema["properties"]["pose"]["properties"]["theta"] == {"type": "number"}
    assert schema_name(RobotOdometry) == "hilnav.RobotOdometry"


@pytest.mark.parametrize(
    "a,expect",
    [
        (0.0, 0.0),
        (math.pi, math.pi),
        (-math.pi, math.pi),
        (3 * math.pi, math.pi),
        (7.0, 7 - 2 * math.pi),
    ],
)
def test_wrap_angle(a, expect):
    assert wrap_angle(a) == pytest.approx(expect)
