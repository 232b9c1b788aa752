"""Foxglove's official JSON Schemas of the messages a log carries in Foxglove form.

The schemas are Foxglove's own files, vendored unchanged from the npm package
``@foxglove/schemas`` (``hilnav/log/schemas/``, package data; its README says how they were
taken and under which licence). Two groups:

- :data:`SCHEMAS`: the *views* (:mod:`hilnav.log.foxglove`), written beside a native
  message; the reader recognises a view by its schema name and does not decode it back;
- :data:`NATIVE`: hilnav messages that *are* a Foxglove message (the map,
  ``msgs.OccupancyGridMsg``, is a ``foxglove.Grid``); their channels carry the official
  schema, and the reader decodes them as hilnav messages.

:func:`official_schema` gives either by name.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources
from typing import Any

VIEW_NAMES = ("PoseInFrame", "FrameTransform", "LocationFix", "SceneUpdate")
NATIVE_NAMES = ("Grid",)


@cache
def _load(name: str) -> dict[str, Any]:
    """The vendored schema ``<name>.json`` (title ``foxglove.<name>``)."""
    text = resources.files("hilnav.log").joinpath("schemas", f"{name}.json").read_text("utf-8")
    schema = json.loads(text)
    if schema.get("title") != f"foxglove.{name}":
        raise ValueError(f"schemas/{name}.json is titled {schema.get('title')!r}")
    return schema


SCHEMAS: dict[str, dict[str, Any]] = {f"foxglove.{n}": _load(n) for n in VIEW_NAMES}
NATIVE: dict[str, dict[str, Any]] = {f"foxglove.{n}": _load(n) for n in NATIVE_NAMES}


def official_schema(schema_name: str) -> dict[str, Any] | None:
    """Foxglove's JSON Schema named ``schema_name`` (a view's or a native one), else None."""
    return SCHEMAS.get(schema_name) or NATIVE.get(schema_name)
