"""msgs.construct: the positional constructor makes the object __init__ makes."""

from __future__ import annotations

import dataclasses

from msgs import GpsFix, IrScan, Pose2D
from msgs.construct import positional_constructor


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
