"""The NMEA readers' tables of what recent fields read as, in one registry.

A receiver repeats its fields from epoch to epoch (a time shared by GGA, RMC and ZDA, a
position by GGA and RMC, the DOPs, a GSA, a GSV's satellites, ...): the readers keep what
a field's text read as in small tables (module-level dicts, emptied when full). A table
maps text to what reading it gives, so it never changes a result, only how fast it
comes: :func:`clear_caches` empties every table (tests/test_nmea_fastpath.py checks the
results are the same; bench/codecs.py decodes each stream from empty tables, so that a
stream decoded again does not find its own fields read already).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")
_CLEARS: list[Callable[[], object]] = []


def table(d: T) -> T:
    """Register a module-level dict (or anything with ``clear()``) as a table; returns it."""
    _CLEARS.append(d.clear)  # type: ignore[attr-defined]
    return d


def on_clear(clear: Callable[[], object]) -> None:
    """Register what empties a table that is not a dict (an lru_cache, a last value)."""
    _CLEARS.append(clear)


def clear_caches() -> None:
    """Empty every table of the NMEA readers."""
    for clear in _CLEARS:
        clear()
