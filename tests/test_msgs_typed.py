"""msgs.typed: the one walk from plain values to typed dataclasses, under two policies
(the message codec and the config loader) that word their errors differently."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import pytest

from hilnav.config import ConfigError, parse_config
from msgs import DecodeError, RobotOdometry, from_dict
from msgs.typed import TypedReader, hints, join


@dataclass(frozen=True)
class Inner:
    xs: tuple[float, ...]
    pair: tuple[int, str] = (0, "")


@dataclass(frozen=True)
class Outer:
    inner: Inner
    kind: Literal["a", "b"] = "a"
    maybe: int | None = None
    table: dict[str, int] = field(default_factory=dict)


class Strict(TypedReader):
    """A minimal policy: ints only, records from dicts, unknown keys ignored."""

    def scalar(self, tp, value, path):
        if tp in (int, float) and isinstance(value, int | float) and not isinstance(value, bool):
            return tp(value)
        if tp is str and isinstance(value, str):
            return value
        raise self.fail("type", tp, value, path)

    def record(self, cls, value, path):
        if not isinstance(value, dict):
            raise self.fail("mapping", cls, value, path)
        h = hints(cls)
        return cls(**{k: self.read(h[k], v, join(path, k)) for k, v in value.items() if k in h})


def test_the_walk_reads_every_kind_of_hint():
    data = {"inner": {"xs": [1, 2.5], "pair": [3, "z"]}, "kind": "b", "maybe": 4, "table": {"k": 1}}
    got = Strict().read(Outer, data, "")
    assert got == Outer(Inner((1.0, 2.5), (3, "z")), "b", 4, {"k": 1})
    assert Strict().read(Outer, {"inner": {"xs": []}, "maybe": None}, "").maybe is None


@pytest.mark.parametrize(
    ("data", "path", "kind"),
    [
        ({"inner": {"xs": [1, "x"]}}, "inner.xs[1]", "type"),
        ({"inner": {"xs": 3}}, "inner.xs", "list"),
        ({"inner": {"xs": [], "pair": [1]}}, "inner.pair", "length"),
        ({"inner": {"xs": []}, "kind": "c"}, "kind", "literal"),
        ({"inner": {"xs": []}, "maybe": "x"}, "maybe", "union"),
        ({"inner": {"xs": []}, "table": {"k": "v"}}, "table.k", "type"),
        ({"inner": {"xs": []}, "table": []}, "table", "mapping"),
    ],
)
def test_errors_name_the_path_and_the_problem(data, path, kind):
    with pytest.raises(ValueError) as err:
        Strict().read(Outer, data, "")
    assert str(err.value).startswith(f"{path}: ") and f"({kind})" in str(err.value)


def test_codec_and_config_keep_their_own_wording():
    odo = {"stamp_ns": 1, "pose": {"theta": "x"}, "left_vel_mps": 0, "right_vel_mps": 0,
           "linear_vel_mps": 0, "angular_vel_radps": 0, "battery_v": 12, "moving": False,
           "motors_enabled": False}  # fmt: skip
    with pytest.raises(DecodeError, match=r"^pose\.theta: expected a number, got 'x'$"):
        from_dict(RobotOdometry, odo)
    with pytest.raises(ConfigError, match=r"geometry\.ir_mounts\[0\] = \[0\.2\]: expected 3"):
        parse_config({"geometry": {"ir_mounts": [[0.2]]}}, "r1.toml")
