"""msgs.codec's msgspec fast path against its reference path (the typed walk and json).

The fast decode must accept only what the reference walk accepts, and build the same
message; the fast encode must give a payload that decodes to what the reference encoding
decodes to (NaN and infinities included). Messages come from hypothesis' strategies for
the dataclasses' own type hints; hostile payloads are valid ones with one field replaced
by any JSON value.
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import msgs
from msgs.codec import _decoder, _encode_reference
from msgs.fast import plan

CLASSES = [
    getattr(msgs, name)
    for name in msgs.__all__
    if isinstance(getattr(msgs, name), type) and dataclasses.is_dataclass(getattr(msgs, name))
]

json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**70), 2**70)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.sampled_from(["nan", "inf", "-inf", "AP8=", "ok", "", "x_ns"])
    | st.text(max_size=5),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=6), inner),
    max_leaves=8,
)


def reference(cls: type, payload: bytes) -> object:
    """The reference walk's answer: the message, or the DecodeError it raises."""
    try:
        return _decoder("").record(cls, json.loads(payload), "")
    except (msgs.DecodeError, RecursionError) as exc:
        return exc


def same(a: object, b: object) -> bool:
    return type(a) is type(b) and repr(a) == repr(b)  # repr: NaN equals NaN


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.__name__)
@settings(
    max_examples=20, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
@given(data=st.data())
def test_fast_encode_and_decode_agree_with_the_reference(cls, data):
    msg = data.draw(st.from_type(cls))
    fast = msgs.encode(msg)
    ref = _encode_reference(msg)
    assert json.loads(fast) == json.loads(ref) or same(msgs.decode(cls, fast), reference(cls, ref))
    expected = reference(cls, ref)
    if isinstance(expected, Exception):  # e.g. an int beyond 64 bits: refused both ways
        with pytest.raises(msgs.DecodeError):
            msgs.decode(cls, fast)
    else:
        assert same(msgs.decode(cls, fast), expected)


@pytest.mark.parametrize("cls", CLASSES, ids=lambda c: c.__name__)
@settings(
    max_examples=30, derandomize=True, deadline=None, suppress_health_check=[HealthCheck.too_slow]
)
@given(data=st.data())
def test_fast_decode_accepts_nothing_the_reference_refuses(cls, data):
    body = json.loads(_encode_reference(data.draw(st.from_type(cls))))
    field = data.draw(st.sampled_from(sorted(body)))
    if data.draw(st.booleans()):
        body[field] = data.draw(json_values)
    else:
        del body[field]
    payload = json.dumps(body).encode()
    fast = plan(cls).decode(payload)
    expected = reference(cls, payload)
    if fast is not None:
        assert same(fast, expected)
    got = msgs.decode(cls, payload) if not isinstance(expected, Exception) else None
    if got is not None:
        assert same(got, expected)


def test_non_finite_floats_travel_as_strings_and_decode_back():
    box = msgs.PoseBox(
        1, "r1", msgs.Interval(0, 1), msgs.Interval(2, 3), msgs.Interval(-math.inf, math.inf)
    )
    data = msgs.encode(box)
    assert b'"-inf"' in data and b'"inf"' in data and b"null" not in data
    assert msgs.decode(msgs.PoseBox, data) == box
    fix = msgs.GpsFix(5, lat_deg=1.0, hdop=math.nan, vdop=None)
    back = msgs.decode(msgs.GpsFix, msgs.encode(fix))
    assert math.isnan(back.hdop) and back.vdop is None and back.lat_deg == 1.0


def test_numpy_scalars_encode_as_numbers():
    msg = msgs.GyroSample(np.int64(3), np.float64(0.5), np.float32(0.25))
    assert json.loads(msgs.encode(msg)) == {
        "stamp_ns": 3,
        "rate_radps": 0.5,
        "angle_rad": 0.25,
        "angle_wrapped_rad": 0.0,
    }


@pytest.mark.parametrize(
    "payload, match",
    [
        (b'{"stamp_ns": 9223372036854775808, "rate_radps": 0, "angle_rad": 0}', "64 bits"),
        (b'{"stamp_ns": -1, "rate_radps": 0, "angle_rad": 0}', "negative"),
        (b'{"stamp_ns": 1, "stamp_ns": -1, "rate_radps": 0, "angle_rad": 0}', "negative"),
        (b'{"stamp_ns": 1, "rate_radps": true, "angle_rad": 0}', "number"),
    ],
)
def test_the_fast_path_leaves_refusals_to_the_walk(payload, match):
    assert plan(msgs.GyroSample).decode(payload) is None
    with pytest.raises(msgs.DecodeError, match=match):
        msgs.decode(msgs.GyroSample, payload)


def test_dict_values_under_a_stamp_key_are_checked_like_stamps():
    payload = json.dumps(
        {"stamp_ns": 1, "name": "p", "robot_class": "", "subclass": "", "config": {"t_ns": -2}}
    ).encode()
    assert plan(msgs.RobotInfo).decode(payload) is None
    with pytest.raises(msgs.DecodeError, match="config.t_ns"):
        msgs.decode(msgs.RobotInfo, payload)
