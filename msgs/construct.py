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
:func:`expression_constructor` is the same with each field given by an expression over
parameters of the caller's choice (a decoder passes the object it reads the values from,
not the values: ``{"lat_deg": "f.lat"}``), the others their defaults.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")


def positional_constructor(cls: type[T]) -> Callable[..., T]:
    """``f(v1, ..., vn) == cls(v1, ..., vn)`` for all n fields, faster (module doc)."""
    if not _fillable(cls):
        return cls
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    make = expression_constructor(
        cls,
        ", ".join(f"v{i}" for i in range(len(names))),
        {n: f"v{i}" for i, n in enumerate(names)},
    )
    make.__doc__ = f"{cls.__name__}(...) with every field given positionally."
    return make


def expression_constructor(
    cls: type[T], params: str, values: dict[str, str], env: dict[str, Any] | None = None
) -> Callable[..., T]:
    """A function ``f(params)`` that makes ``cls(**{name: eval(values[name])})``: each
    field given by an expression over the parameters (source text, evaluated in ``env``;
    a field not in ``values`` gets its default), as fast as :func:`positional_constructor`.
    A caller that would read an object's attributes into variables only to pass them on
    reads them in the expressions instead (``{"lat_deg": "f.lat"}``). For a class the
    fast way does not apply to, the function calls ``cls`` with the same values."""
    fields = dataclasses.fields(cls)  # type: ignore[arg-type]
    unknown = set(values) - {f.name for f in fields}
    if unknown:
        raise ValueError(f"{cls.__name__} has no fields {sorted(unknown)}")
    exprs = {}
    for f in fields:
        if f.name in values:
            exprs[f.name] = f"({values[f.name]})"
        elif f.default is not dataclasses.MISSING:
            exprs[f.name] = f"_default_{f.name}"
        elif f.default_factory is not dataclasses.MISSING:
            exprs[f.name] = f"_factory_{f.name}()"
        else:
            raise ValueError(f"{cls.__name__}.{f.name} has no value and no default")
    scope: dict[str, Any] = dict(env or {})
    for f in fields:
        scope[f"_default_{f.name}"] = f.default
        scope[f"_factory_{f.name}"] = f.default_factory
    scope["_cls"] = cls
    if not _fillable(cls):
        args = ", ".join(f"{n}={e}" for n, e in exprs.items())
        src = f"def make({params}):\n    return _cls({args})\n"
    else:
        twin = type(f"_{cls.__name__}Builder", (), {"__slots__": cls.__slots__})  # type: ignore[attr-defined]
        scope["_twin"] = twin
        try:  # a twin's instance may become a ``cls`` (same slots, same layout)?
            twin().__class__ = cls
            body = [f"    o.{name} = {e}" for name, e in exprs.items()]
            head, tail = "    o = _twin()", "    o.__class__ = _cls"
        except TypeError:
            scope["_new"] = object.__new__
            for i, name in enumerate(exprs):
                scope[f"_s{i}"] = cls.__dict__[name].__set__
            body = [f"    _s{i}(o, {e})" for i, e in enumerate(exprs.values())]
            head, tail = "    o = _new(_cls)", ""
        src = f"def make({params}):\n{head}\n" + "\n".join(body) + f"\n{tail}\n    return o\n"
    exec(src, scope)  # the way dataclasses builds __init__ itself
    return scope["make"]


def _fillable(cls: type) -> bool:
    """A frozen, slotted dataclass without __post_init__ whose fields are its slots (in
    order) and all of them __init__ arguments: one the module's way may build."""
    if not dataclasses.is_dataclass(cls) or hasattr(cls, "__post_init__"):
        return False
    fields = dataclasses.fields(cls)
    names = tuple(f.name for f in fields)
    return tuple(getattr(cls, "__slots__", ())) == names and all(f.init for f in fields)
