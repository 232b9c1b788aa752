"""``hilnav log cat``: a log's messages as text, one line each (like ``mcap cat``).

Each line holds the log time (ns), the topic, the schema name and the JSON payload, in
log-time order for a finished file and file order for a truncated one
(:func:`hilnav.log.reader.iter_raw`). With ``as_json`` a line is one JSON object instead:
``log_time_ns``, ``publish_time_ns``, ``topic``, ``schema`` and ``message`` (the payload
parsed), or ``data_base64`` for a payload that is not JSON. ``topics`` keeps the MCAP
topics named, exactly or by ``fnmatch`` pattern (``/r1/*``).
"""

from __future__ import annotations

import base64
import json
from collections.abc import Iterable, Iterator
from fnmatch import fnmatchcase
from pathlib import Path

from hilnav.log.reader import RawRecord, iter_raw


def wanted(topic: str, patterns: Iterable[str]) -> bool:
    """True when a pattern names the topic, exactly or by ``fnmatch``."""
    return any(topic == p or fnmatchcase(topic, p) for p in patterns)


def _payload(r: RawRecord) -> str | None:
    """The JSON payload as text, or None when it is not JSON."""
    if r.message_encoding != "json":
        return None
    try:
        text = r.data.decode("utf-8")
        json.loads(text)
    except ValueError:  # UnicodeDecodeError is one
        return None
    return text


def line(r: RawRecord, as_json: bool = False) -> str:
    """One record as a line of text (see the module docstring)."""
    text = _payload(r)
    if not as_json:
        body = text if text is not None else f"<{len(r.data)} bytes {r.message_encoding}>"
        return f"{r.log_time_ns} {r.topic} [{r.schema_name}] {body}"
    out: dict = {
        "log_time_ns": r.log_time_ns,
        "publish_time_ns": r.publish_time_ns,
        "topic": r.topic,
        "schema": r.schema_name,
    }
    if text is not None:
        out["message"] = json.loads(text)
    else:
        out["data_base64"] = base64.b64encode(r.data).decode("ascii")
    return json.dumps(out, separators=(",", ":"))


def cat_lines(
    path: str | Path, topics: Iterable[str] | None = None, as_json: bool = False
) -> Iterator[str]:
    """The lines of a log's messages (views and raw bytes included)."""
    patterns = tuple(topics or ())
    for r in iter_raw(path):
        if not patterns or wanted(r.topic, patterns):
            yield line(r, as_json)
