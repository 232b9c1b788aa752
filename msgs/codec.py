"""One JSON encoding for every message, shared by the Zenoh bus and the MCAP log.

Messages are frozen dataclasses of plain values (int, float, str, bool, bytes, tuples,
nested message dataclasses, optional fields). ``encode`` turns one into compact UTF-8
JSON, ``decode`` rebuilds it and checks the types, raising :class:`DecodeError` with the
offending field named, so a malformed payload from the bus is counted and skipped rather
than crashing a service. ``decode`` is the boundary check for everything that arrives from
outside: payloads over ``max_bytes`` or nested deeper than Python can parse are refused,
integers must fit in 64 bits (MCAP and Zenoh stamps are uint64), ``*_ns`` stamps must lie
in ``[0, 2**63)``, and a class that sets ``FLOATS = "finite"`` (commands) or
``FLOATS = "no_nan"`` (pose boxes, whose heading may be unbounded) gets every float of
it, nested ones included, checked. ``json_schema`` derives a JSON Schema from the type
hints, for the MCAP schema records. ``bytes`` fields travel as base64 strings (as
Foxglove expects); a non-finite float as the string "nan", "inf" or "-inf".

Both directions run on msgspec (its C encoder and typed decoder over the dataclasses), one
plan per class (:mod:`msgs.fast`):

- ``encode``: msgspec writes NaN and infinity as ``null``, so a payload with a ``null``
  that the message's ``None`` fields do not account for is made again by the reference
  path (:func:`to_dict`, then msgspec), which writes them as strings;
- ``decode``: msgspec checks the JSON and every type (bool is no int, floats finite,
  base64 valid, literals, tuple lengths, missing fields), then the plan's checks of the
  integers (64 bits, stamps not negative). Any payload the fast path refuses, or that
  holds a non-finite float (a string in JSON), goes through the reference walk over the
  type hints (msgs.typed, shared with the config loader), which accepts exactly what it
  always did and names the offending field. The fast path accepts a subset of what the
  walk accepts and builds the same message.
"""

from __future__ import annotations

import base64
import dataclasses
import json
import math
import types
import typing
from functools import cache
from typing import Any, TypeVar

from msgs.fast import ENCODER, plan
from msgs.typed import TypedReader, hints, join

T = TypeVar("T")


class DecodeError(ValueError):
    """A payload that is not a valid message of the expected type."""


MAX_PAYLOAD_BYTES = 16 * 1024 * 1024  # a whole occupancy grid fits; a flood of junk does not
_I64 = 2**63


def _plain(value: Any) -> Any:
    t = type(value)  # the common exact types first, then the general rules
    if t is float:
        return value if value - value == 0.0 else _non_finite(value)
    if t is int or t is str or t is bool or value is None:
        return value
    if t is tuple or t is list:
        return [_plain(v) for v in value]
    names = _field_names(t)
    if names is not None:
        return {name: _plain(getattr(value, name)) for name in names}
    if isinstance(value, bytes | bytearray | memoryview):
        return base64.b64encode(bytes(value)).decode("ascii")
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, float) and not math.isfinite(value):
        return _non_finite(value)
    if hasattr(value, "item") and callable(value.item):  # numpy scalar
        return _plain(value.item())
    return value


def _non_finite(value: float) -> str:
    # JSON has no inf/nan: encoded as strings understood by decode().
    return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")


@cache
def _field_names(cls: type) -> tuple[str, ...] | None:
    """The field names of a dataclass type (None for any other type)."""
    if not dataclasses.is_dataclass(cls):
        return None
    return tuple(f.name for f in dataclasses.fields(cls))


def to_dict(msg: Any) -> dict[str, Any]:
    """The message as plain JSON-able Python values."""
    return _plain(msg)


def encode(msg: Any) -> bytes:
    """Compact JSON bytes of a message dataclass."""
    try:
        data = ENCODER.encode(msg)
    except (TypeError, ValueError, OverflowError):  # an odd value: the reference path says
        return _encode_reference(msg)
    if b"null" in data and not plan(type(msg)).nulls_are_nones(msg, data):
        return _encode_reference(msg)  # NaN or infinity somewhere: strings, not null
    return data


def _encode_reference(msg: Any) -> bytes:
    """The message through :func:`to_dict` (non-finite floats as strings), then JSON."""
    return ENCODER.encode(_plain(msg))


class _Decoder(TypedReader):
    """The codec's policy over msgs.typed: DecodeError naming the field; integers in 64
    bits, ``*_ns`` stamps not negative; floats from numbers or "nan"/"inf"/"-inf", checked
    by the ``FLOATS`` policy of the outermost class that sets one; bytes from base64;
    unknown keys ignored (newer senders), missing fields without a default refused."""

    error = DecodeError

    def __init__(self, floats: str = "") -> None:
        self.floats = floats

    def fail(self, kind: str, tp: Any, value: Any, path: str) -> DecodeError:
        if kind == "list":
            return DecodeError(f"{path}: expected a list, got {type(value).__name__}")
        if kind == "length":
            return DecodeError(
                f"{path}: expected {len(typing.get_args(tp))} items, got {len(value)}"
            )
        if kind == "mapping":
            return DecodeError(f"{path}: expected an object")
        if kind == "literal":
            return DecodeError(f"{path}: {value!r} not one of {typing.get_args(tp)}")
        if kind == "union":
            return DecodeError(f"{path}: {value!r} fits none of {tp}")
        return DecodeError(f"{path}: unsupported field type {tp}")

    def scalar(self, tp: Any, value: Any, path: str) -> Any:
        if tp is float:
            return self._float(value, path)
        if tp is int:
            if isinstance(value, bool) or not isinstance(value, int):
                raise DecodeError(f"{path}: expected an integer, got {value!r}")
            if not -_I64 <= value < _I64:
                raise DecodeError(f"{path}: integer {value} does not fit in 64 bits")
            if path.endswith("_ns") and value < 0:
                raise DecodeError(f"{path}: a stamp must not be negative, got {value}")
            return value
        if tp is bool:
            if not isinstance(value, bool):
                raise DecodeError(f"{path}: expected true/false, got {value!r}")
            return value
        if tp is str:
            if not isinstance(value, str):
                raise DecodeError(f"{path}: expected a string, got {value!r}")
            return value
        if tp is bytes:
            if not isinstance(value, str):
                raise DecodeError(f"{path}: expected base64 text, got {value!r}")
            try:
                return base64.b64decode(value, validate=True)
            except ValueError as exc:
                raise DecodeError(f"{path}: bad base64: {exc}") from None
        raise self.fail("type", tp, value, path)

    def _float(self, value: Any, path: str) -> float:
        if isinstance(value, str) and value in ("nan", "inf", "-inf"):
            value = float(value)
        elif isinstance(value, bool) or not isinstance(value, int | float):
            raise DecodeError(f"{path}: expected a number, got {value!r}")
        try:
            value = float(value)
        except OverflowError:
            raise DecodeError(f"{path}: number {value} is out of range") from None
        floats = self.floats
        if floats and (value != value or (floats == "finite" and not math.isfinite(value))):
            raise DecodeError(f"{path}: must be a {floats.replace('_', '-')} number, got {value}")
        return value

    def record(self, cls: type, value: Any, path: str) -> Any:
        if not isinstance(value, dict):
            where = path or cls.__name__
            raise DecodeError(f"{where}: expected an object, got {type(value).__name__}")
        reader = self if self.floats else _decoder(getattr(cls, "FLOATS", ""))
        types_ = hints(cls)
        kwargs = {}
        for f in dataclasses.fields(cls):  # type: ignore[arg-type]
            sub = join(path, f.name)
            if f.name in value:
                kwargs[f.name] = reader.read(types_[f.name], value[f.name], sub)
            elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise DecodeError(f"{cls.__name__}: missing field {sub!r}")
        return cls(**kwargs)


@cache
def _decoder(floats: str) -> _Decoder:
    return _Decoder(floats)


def from_dict(cls: type[T], data: Any) -> T:
    """Rebuild a message from plain values; unknown keys are ignored (newer senders)."""
    return _decoder("").record(cls, data, "")


def decode(
    cls: type[T],
    payload: bytes | bytearray | memoryview | str,
    max_bytes: int = MAX_PAYLOAD_BYTES,
) -> T:
    """Parse JSON bytes into ``cls``; raises DecodeError on anything malformed, too large
    (``max_bytes``) or too deeply nested."""
    if len(payload) > max_bytes:
        raise DecodeError(f"{cls.__name__}: payload of {len(payload)} bytes (limit {max_bytes})")
    msg = plan(cls).decode(payload)
    if msg is not None:
        return msg
    try:
        data = json.loads(bytes(payload) if not isinstance(payload, str) else payload)
    except (ValueError, UnicodeDecodeError) as exc:
        raise DecodeError(f"{cls.__name__}: not JSON: {exc}") from None
    except RecursionError:
        raise DecodeError(f"{cls.__name__}: nested too deeply") from None
    try:
        return _decoder("").record(cls, data, "")
    except RecursionError:
        raise DecodeError(f"{cls.__name__}: nested too deeply") from None
    except (TypeError, ValueError) as exc:
        if isinstance(exc, DecodeError):
            raise
        raise DecodeError(f"{cls.__name__}: {exc}") from None


def _schema_of(tp: Any) -> dict[str, Any]:
    origin = typing.get_origin(tp)
    if origin in (typing.Union, types.UnionType):
        return {"anyOf": [_schema_of(a) for a in typing.get_args(tp)]}
    if tp is type(None):
        return {"type": "null"}
    if origin is tuple:
        args = typing.get_args(tp)
        if len(args) == 2 and args[1] is Ellipsis:
            return {"type": "array", "items": _schema_of(args[0])}
        return {"type": "array", "prefixItems": [_schema_of(a) for a in args]}
    if origin is dict:
        return {"type": "object", "additionalProperties": _schema_of(typing.get_args(tp)[1])}
    if origin is typing.Literal:
        return {"enum": list(typing.get_args(tp))}
    if dataclasses.is_dataclass(tp):
        return json_schema(tp)
    return {
        float: {"type": "number"},
        int: {"type": "integer"},
        bool: {"type": "boolean"},
        str: {"type": "string"},
        bytes: {"type": "string", "contentEncoding": "base64"},
    }.get(tp, {})


@cache
def _json_schema(cls: type) -> str:
    props = {f.name: _schema_of(hints(cls)[f.name]) for f in dataclasses.fields(cls)}
    schema: dict[str, Any] = {"type": "object", "title": cls.__name__, "properties": props}
    if cls.__doc__:
        schema["description"] = cls.__doc__.strip().splitlines()[0]
    return json.dumps(schema)


def json_schema(cls: type) -> dict[str, Any]:
    """JSON Schema (draft 2020-12 subset) of a message dataclass, from its type hints."""
    return json.loads(_json_schema(cls))


def schema_name(cls: type) -> str:
    """Schema name for logs: a class may set SCHEMA_NAME, else ``hilnav.<ClassName>``."""
    return getattr(cls, "SCHEMA_NAME", f"hilnav.{cls.__name__}")
