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
it, nested ones included, checked. ``json_schema`` derives a JSON Schema from the type hints, for
the MCAP schema records. ``bytes`` fields travel as base64 strings (as Foxglove expects).
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

T = TypeVar("T")


class DecodeError(ValueError):
    """A payload that is not a valid message of the expected type."""


MAX_PAYLOAD_BYTES = 16 * 1024 * 1024  # a whole occupancy grid fits; a flood of junk does not
_I64 = 2**63


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, bytes | bytearray | memoryview):
        return base64.b64encode(bytes(value)).decode("ascii")
    if isinstance(value, tuple | list):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, float) and not math.isfinite(value):
        # JSON has no inf/nan: encode as strings understood by decode().
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if hasattr(value, "item") and callable(value.item):  # numpy scalar
        return _plain(value.item())
    return value


def to_dict(msg: Any) -> dict[str, Any]:
    """The message as plain JSON-able Python values."""
    return _plain(msg)


def encode(msg: Any) -> bytes:
    """Compact JSON bytes of a message dataclass."""
    return json.dumps(_plain(msg), separators=(",", ":"), allow_nan=False).encode("utf-8")


@cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _build(tp: Any, value: Any, path: str, floats: str = "") -> Any:
    origin = typing.get_origin(tp)
    if tp is Any:
        return value
    if origin in (typing.Union, types.UnionType):
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _build(arg, value, path, floats)
            except DecodeError as exc:
                errors.append(str(exc))
        raise DecodeError(f"{path}: {value!r} fits none of {tp}")
    if origin is tuple:
        args = typing.get_args(tp)
        if not isinstance(value, list):
            raise DecodeError(f"{path}: expected a list, got {type(value).__name__}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_build(args[0], v, f"{path}[{i}]", floats) for i, v in enumerate(value))
        if len(args) != len(value):
            raise DecodeError(f"{path}: expected {len(args)} items, got {len(value)}")
        return tuple(
            _build(a, v, f"{path}[{i}]", floats)
            for i, (a, v) in enumerate(zip(args, value, strict=True))
        )
    if origin is dict:
        kt, vt = typing.get_args(tp)
        if not isinstance(value, dict):
            raise DecodeError(f"{path}: expected an object")
        return {_build(kt, k, path): _build(vt, v, f"{path}.{k}", floats) for k, v in value.items()}
    if origin is typing.Literal:
        if value not in typing.get_args(tp):
            raise DecodeError(f"{path}: {value!r} not one of {typing.get_args(tp)}")
        return value
    if dataclasses.is_dataclass(tp):
        return _from_dict(tp, value, path, floats)
    if tp is float:
        if isinstance(value, str) and value in ("nan", "inf", "-inf"):
            value = float(value)
        elif isinstance(value, bool) or not isinstance(value, int | float):
            raise DecodeError(f"{path}: expected a number, got {value!r}")
        try:
            value = float(value)
        except OverflowError:
            raise DecodeError(f"{path}: number {value} is out of range") from None
        if floats and (value != value or (floats == "finite" and not math.isfinite(value))):
            raise DecodeError(f"{path}: must be a {floats.replace('_', '-')} number, got {value}")
        return value
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
    raise DecodeError(f"{path}: unsupported field type {tp}")


def _from_dict(cls: type[T], data: Any, path: str, floats: str = "") -> T:
    if not isinstance(data, dict):
        raise DecodeError(f"{path or cls.__name__}: expected an object, got {type(data).__name__}")
    hints = _hints(cls)
    floats = floats or getattr(cls, "FLOATS", "")
    kwargs = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        sub = f"{path}.{f.name}" if path else f.name
        if f.name in data:
            kwargs[f.name] = _build(hints[f.name], data[f.name], sub, floats)
        elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            raise DecodeError(f"{cls.__name__}: missing field {sub!r}")
    return cls(**kwargs)


def from_dict(cls: type[T], data: Any) -> T:
    """Rebuild a message from plain values; unknown keys are ignored (newer senders)."""
    return _from_dict(cls, data, "")


def decode(
    cls: type[T],
    payload: bytes | bytearray | memoryview | str,
    max_bytes: int = MAX_PAYLOAD_BYTES,
) -> T:
    """Parse JSON bytes into ``cls``; raises DecodeError on anything malformed, too large
    (``max_bytes``) or too deeply nested."""
    if len(payload) > max_bytes:
        raise DecodeError(f"{cls.__name__}: payload of {len(payload)} bytes (limit {max_bytes})")
    try:
        data = json.loads(bytes(payload) if not isinstance(payload, str) else payload)
    except (ValueError, UnicodeDecodeError) as exc:
        raise DecodeError(f"{cls.__name__}: not JSON: {exc}") from None
    except RecursionError:
        raise DecodeError(f"{cls.__name__}: nested too deeply") from None
    try:
        return _from_dict(cls, data, "")
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
    hints = _hints(cls)
    props = {f.name: _schema_of(hints[f.name]) for f in dataclasses.fields(cls)}
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
