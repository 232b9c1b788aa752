"""Fast construction of messages on decoders' hot paths.

A frozen dataclass's ``__init__`` sets every field through ``object.__setattr__`` (the
frozen check makes a plain assignment raise), a global look-up and a call per field: a
44-field :class:`msgs.GpsFix` costs about 4 us. :func:`positional_constructor` builds,
once per slotted class, a function that fills an instance of a plain twin class with the
same ``__slots__`` (plain attribute stores, which the interpreter specialises to a direct
slot write) and then gives it the message's class (``__class__`` assignment, allowed
between classes of the same slots and layout): the same object, equal to the one
``__init__`` makes, in about an eighth of the time. Where the interpreter refuses the
class assignment it falls back to calling each field's slot descriptor (half the time of
``__init__``).

It applies to frozen, slotted dataclasses without ``__post_init__`` (every message);
for any other class (a message type that changes its representation later) it returns the
class itself, so callers stay correct. The function takes every field, positionally, in
declaration order: no defaults, no checks (the decoders pass values of the right types).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")


def positional_constructor(cls: type[T]) -> Callable[..., T]:
    """``f(v1, ..., vn) == cls(v1, ..., vn)`` for all n fields, faster (module doc)."""
    if not dataclasses.is_dataclass(cls) or hasattr(cls, "__post_init__"):
        return cls
    names = [f.name for f in dataclasses.fields(cls)]
    if tuple(getattr(cls, "__slots__", ())) != tuple(names) or not all(
        f.init for f in dataclasses.fields(cls)
    ):
        return cls
    args = [f"v{i}" for i in range(len(names))]
    twin = type(f"_{cls.__name__}Builder", (), {"__slots__": cls.__slots__})  # type: ignore[attr-defined]
    env: dict[str, Any] = {"_new": object.__new__, "_cls": cls, "_twin": twin}
    try:  # a twin's instance may become a ``cls`` (same slots, same layout)?
        twin().__class__ = cls
        body = [f"    o.{name} = v{i}" for i, name in enumerate(names)]
        head, tail = "    o = _twin()", "    o.__class__ = _cls"
    except TypeError:
        for i, name in enumerate(names):
            env[f"_s{i}"] = cls.__dict__[name].__set__
        body = [f"    _s{i}(o, v{i})" for i in range(len(names))]
        head, tail = "    o = _new(_cls)", ""
    src = f"def make({', '.join(args)}):\n{head}\n" + "\n".join(body) + f"\n{tail}\n    return o\n"
    exec(src, env)  # the way dataclasses builds __init__ itself
    make = env["make"]
    make.__doc__ = f"{cls.__name__}(...) with every field given positionally."
    return make
