"""msgs.construct: the positional constructor makes the object __init__ makes."""

from __future__ import annotations

import dataclasses

import pytest

from msgs import GpsFix, IrScan, Pose2D
from msgs.construct import expression_constructor, positional_constructor


def test_the_fast_constructor_equals_init_for_messages():
    for cls in (IrScan, GpsFix, Pose2D):
        values = [f"v{i}" if f.type == "str" else i for i, f in enumerate(dataclasses.fields(cls))]
        made = positional_constructor(cls)(*values)
        assert type(made) is cls and made == cls(*values) and hash(made) == hash(cls(*values))


def test_classes_it_cannot_build_faster_are_returned_as_they_are():
    @dataclasses.dataclass(frozen=True)
    class NoSlots:
        a: int

    @dataclasses.dataclass(frozen=True, slots=True)
    class Checked:
        a: int

        def __post_init__(self) -> None:
            if self.a < 0:
                raise ValueError("negative")

    assert positional_constructor(NoSlots) is NoSlots
    assert positional_constructor(Checked) is Checked
    assert positional_constructor(int) is int


def test_the_expression_constructor_equals_init():
    """Fields from expressions over the parameters (the others their defaults), for a
    class built the fast way and for one that is not (its __init__ called)."""

    @dataclasses.dataclass(frozen=True)
    class NoSlots:
        a: int
        b: str = "b"

    class Src:
        lat, lon = 37.5, 127.0

    make = expression_constructor(
        GpsFix, "f, stamp, mode", {"stamp_ns": "stamp", "lat_deg": "f.lat", "lon_deg": "f.lon",
                                    "mode": "mode + 1", "talker": "'GP'"}
    )  # fmt: skip
    made = make(Src, 7, 2)
    assert type(made) is GpsFix
    assert made == GpsFix(7, lat_deg=37.5, lon_deg=127.0, mode=3, talker="GP")
    assert expression_constructor(NoSlots, "x", {"a": "x * 2"})(4) == NoSlots(8)
    with pytest.raises(ValueError, match="no fields"):
        expression_constructor(NoSlots, "x", {"c": "x"})
    with pytest.raises(ValueError, match="no value and no default"):
        expression_constructor(NoSlots, "x", {"b": "x"})
