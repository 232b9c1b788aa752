"""The msgspec fast path of :mod:`msgs.codec`: one plan per message class.

``ENCODER`` is msgspec's JSON encoder (numpy scalars as Python numbers). A
:class:`Plan` holds the class's msgspec typed decoder and what the reference walk checks
beyond msgspec's own typed decode: integers inside 64 bits, ``*_ns`` stamps (and dict
values under a ``*_ns`` key) not negative. msgspec already refuses a bool for an int,
non-finite or out-of-range floats, bad base64, values outside a Literal, wrong tuple
lengths and missing fields. A class with a type the plan does not cover (a dict keyed by
anything but str, a union of several checked types) has no decoder and always takes
the reference path. ``Plan.nulls_are_nones`` tells a ``null`` written for a None field
from one msgspec writes for NaN or infinity.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Callable
from functools import cache
from typing import Any

import msgspec

from msgs.typed import hints


def _numpy_scalar(value: Any) -> Any:
    if hasattr(value, "item") and callable(value.item):  # numpy scalar
        return value.item()
    raise TypeError(f"cannot encode {type(value).__name__}")


ENCODER = msgspec.json.Encoder(enc_hook=_numpy_scalar)
_I64 = 2**63
Check = Callable[[Any], bool]


class _Unsupported(Exception):
    """A type the fast path does not cover: the class always takes the reference path."""


def _int_check(ns: bool) -> Check:
    if ns:
        return lambda v: 0 <= v < _I64
    return lambda v: -_I64 <= v < _I64


def _check_of(tp: Any, ns: bool) -> Check | None:
    """What the reference walk checks of a value of type ``tp`` beyond msgspec's typed
    decode (integers: 64 bits, and not negative for a ``*_ns`` stamp): a predicate, or
    None when there is nothing more to check. _Unsupported for types outside the plan."""
    if tp in (float, str, bool, bytes) or tp is Any:
        return None
    if tp is int:
        return _int_check(ns)
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin is typing.Literal:
        return None
    if origin in (typing.Union, types.UnionType):
        members = [a for a in args if a is not type(None)]
        checks = [(a, _check_of(a, ns)) for a in members]
        checks = [(a, c) for a, c in checks if c is not None]
        if not checks:
            return None
        if len(checks) > 1 or checks[0][0] is not int:
            raise _Unsupported(tp)
        int_check = checks[0][1]
        return lambda v: type(v) is not int or int_check(v)
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            item = _check_of(args[0], False)
            return None if item is None else (lambda v: all(map(item, v)))
        items = [_check_of(a, False) for a in args]
        if not any(items):
            return None
        pairs = [(i, c) for i, c in enumerate(items) if c is not None]
        return lambda v: all(c(v[i]) for i, c in pairs)
    if origin is dict:
        if args[0] is not str:
            raise _Unsupported(tp)
        plain, stamp = _check_of(args[1], False), _check_of(args[1], True)
        if plain is None or stamp is None:
            return None
        return lambda d: all((stamp if k.endswith("_ns") else plain)(v) for k, v in d.items())
    if dataclasses.is_dataclass(tp):
        return _record_check(tp)  # type: ignore[arg-type]
    raise _Unsupported(tp)


def _record_check(cls: type) -> Check | None:
    types_ = hints(cls)
    fields = []
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        check = _check_of(types_[f.name], f.name.endswith("_ns"))
        if check is not None:
            fields.append((f.name, check))
    if not fields:
        return None
    return lambda m: all(check(getattr(m, name)) for name, check in fields)


def _may_be_none(tp: Any) -> bool:
    return type(None) in typing.get_args(tp) or tp is Any


def _nested_none(tp: Any) -> bool:
    """Whether a value of type ``tp`` may hold ``None`` below its top level."""
    if dataclasses.is_dataclass(tp):
        types_ = hints(tp)  # type: ignore[arg-type]
        return any(
            _may_be_none(types_[f.name]) or _nested_none(types_[f.name])
            for f in dataclasses.fields(tp)  # type: ignore[arg-type]
        )
    return any(_may_be_none(a) or _nested_none(a) for a in typing.get_args(tp) if a is not ...)


class Plan:
    """How one message class goes through msgspec (see the module docstring)."""

    def __init__(self, cls: type) -> None:
        self.cls = cls
        self.decoder: msgspec.json.Decoder | None = None
        self.check: Check | None = None
        self.optional: tuple[str, ...] = ()
        self.nested_none = True
        if not dataclasses.is_dataclass(cls):
            return
        types_ = hints(cls)
        fields = dataclasses.fields(cls)
        self.optional = tuple(f.name for f in fields if _may_be_none(types_[f.name]))
        self.nested_none = any(_nested_none(types_[f.name]) for f in fields)
        try:
            self.check = _record_check(cls)
            self.decoder = msgspec.json.Decoder(cls)
        except (_Unsupported, TypeError):  # TypeError: a type msgspec cannot decode
            self.decoder = None

    def nulls_are_nones(self, msg: Any, data: bytes) -> bool:
        """True if every ``null`` in ``data`` is one of the message's None fields (then no
        float was NaN or infinite: msgspec writes those as null too)."""
        if self.nested_none or not self.optional:
            return False
        nones = sum(getattr(msg, name, 0) is None for name in self.optional)
        return data.count(b"null") == nones

    def decode(self, payload: Any) -> Any:
        """The message, or None when the reference walk must decide."""
        if self.decoder is None:
            return None
        try:
            msg = self.decoder.decode(payload)
        except Exception:  # malformed, a type msgspec refuses, too deep: the walk decides
            return None
        if self.check is not None and not self.check(msg):
            return None
        return msg


@cache
def plan(cls: type) -> Plan:
    return Plan(cls)
