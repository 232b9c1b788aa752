"""Plain values (parsed JSON or TOML) read into typed dataclasses by their type hints.

One walk shared by the message codec (msgs.codec.decode: bus and log payloads) and the
configuration loader (hilnav.config: TOML files). The type hint drives it: ``Any``,
unions (``X | None``), ``tuple[X, ...]`` and ``tuple[X, Y]`` from lists, ``dict[K, V]``,
``Literal``, nested dataclasses, and scalars; every error names the path of the value
(``devices.ir.port``, ``ranges_m[3]``, ``raw.left``).

What a reader accepts and how it words its errors is its policy, a subclass of
:class:`TypedReader`:

- :meth:`TypedReader.fail` builds the error of a structural problem, ``kind`` one of
  "list" (not a list), "length" (wrong item count of a fixed tuple), "mapping" (not an
  object/table), "literal" (not one of the allowed values), "union" (fits no member);
- :meth:`TypedReader.scalar` checks and converts a leaf (float, int, str, ...);
- :meth:`TypedReader.record` builds a dataclass from a mapping (unknown keys, missing
  fields, extra checks), reading each field with :meth:`TypedReader.read`.

A union tries its members in order and takes the first that reads without raising the
reader's ``error`` type.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from functools import cache
from typing import Any


@cache
def hints(cls: type) -> dict[str, Any]:
    """The resolved type hints of a dataclass (cached)."""
    return typing.get_type_hints(cls)


def join(path: str, name: str) -> str:
    """The path of field ``name`` inside ``path`` ("" at the top)."""
    return f"{path}.{name}" if path else name


class TypedReader:
    """Reads plain values into the type of a hint; see the module docstring."""

    error: type[Exception] = ValueError

    def read(self, tp: Any, value: Any, path: str) -> Any:
        """``value`` read as type ``tp``; errors name ``path``."""
        if tp is Any:
            return value
        origin = typing.get_origin(tp)
        if origin in (typing.Union, types.UnionType):
            return self._union(tp, value, path)
        if origin is tuple:
            return self._tuple(tp, value, path)
        if origin is dict or tp is dict:
            return self._dict(tp, value, path)
        if origin is typing.Literal:
            if value not in typing.get_args(tp):
                raise self.fail("literal", tp, value, path)
            return value
        if dataclasses.is_dataclass(tp):
            return self.record(tp, value, path)
        return self.scalar(tp, value, path)

    # -- policy ---------------------------------------------------------------------------
    def fail(self, kind: str, tp: Any, value: Any, path: str) -> Exception:
        """The error for a structural problem ``kind`` (see the module docstring)."""
        return self.error(f"{path}: {value!r} does not fit {tp} ({kind})")

    def scalar(self, tp: Any, value: Any, path: str) -> Any:
        """A leaf value of type ``tp``."""
        raise self.fail("type", tp, value, path)

    def record(self, cls: type, value: Any, path: str) -> Any:
        """A dataclass ``cls`` from the mapping ``value``."""
        raise self.fail("type", cls, value, path)

    # -- structure ------------------------------------------------------------------------
    def _union(self, tp: Any, value: Any, path: str) -> Any:
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return None
        for arg in args:
            if arg is type(None):
                continue
            try:
                return self.read(arg, value, path)
            except self.error:
                continue
        raise self.fail("union", tp, value, path)

    def _tuple(self, tp: Any, value: Any, path: str) -> tuple:
        args = typing.get_args(tp)
        if not isinstance(value, list):
            raise self.fail("list", tp, value, path)
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(self.read(args[0], v, f"{path}[{i}]") for i, v in enumerate(value))
        if len(args) != len(value):
            raise self.fail("length", tp, value, path)
        return tuple(
            self.read(a, v, f"{path}[{i}]")
            for i, (a, v) in enumerate(zip(args, value, strict=True))
        )

    def _dict(self, tp: Any, value: Any, path: str) -> dict:
        if not isinstance(value, dict):
            raise self.fail("mapping", tp, value, path)
        kt, vt = typing.get_args(tp) or (Any, Any)
        return {self.read(kt, k, path): self.read(vt, v, f"{path}.{k}") for k, v in value.items()}
