"""Codac 2 (PyPI ``codac``, the reference interval library) as the oracle of the interval
property tests: element-wise calls over arrays of intervals, and the three checks.

For each case: (1) ours holds every sampled feasible point; where Codac's result holds
them too (Codac is not always sound: e.g. ``atan2([1, oo], [-oo, oo])`` is empty in
2.1.2) and the case is not one of the documented classes where Codac is looser, (2)
ours contains Codac's result and (3) ours is no wider than it, both up to rounding
(``ulps`` units in the last place of the bound plus an absolute ``abs_tol``).
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import math
from dataclasses import dataclass

import numpy as np

from localization.interval import IV

# Importing Codac switches the whole process to upward rounding (its interval core sets
# the FPU mode once and relies on it): that would change every later float computation
# of the test session (hypothesis refuses to import under it). Restore the mode at once,
# and switch to Codac's only around calls into Codac (``with CODAC:``).
_libm = ctypes.CDLL(ctypes.util.find_library("m"))
_NEAREST = _libm.fegetround()
import codac  # noqa: E402

_CODAC_MODE = _libm.fegetround()
_libm.fesetround(_NEAREST)


@contextlib.contextmanager
def _codac_rounding():
    old = _libm.fegetround()
    _libm.fesetround(_CODAC_MODE)
    try:
        yield
    finally:
        _libm.fesetround(old)


CODAC = _codac_rounding  # use as ``with CODAC():``

OO = codac.oo
TAU = 2.0 * math.pi


def civ(lo: float, hi: float) -> codac.Interval:
    if not lo <= hi or lo == math.inf or hi == -math.inf:
        return codac.Interval.empty()
    return codac.Interval(float(lo), float(hi))


def civs(iv: IV) -> list[codac.Interval]:
    return [civ(a, b) for a, b in zip(np.ravel(iv.lo), np.ravel(iv.hi), strict=True)]


def ends(ivs) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) arrays of Codac intervals; empties as (inf, -inf)."""
    lo = np.array([math.inf if i.is_empty() else i.lb() for i in ivs])
    hi = np.array([-math.inf if i.is_empty() else i.ub() for i in ivs])
    return lo, hi


def ulps_out(b: np.ndarray, n: int, direction: float) -> np.ndarray:
    with np.errstate(over="ignore"):
        for _ in range(n):
            b = np.nextafter(b, direction)
    return b


def _widen(b: np.ndarray, ulps: int, abs_tol: np.ndarray, direction: float) -> np.ndarray:
    """``b`` moved ``ulps`` floats and then ``abs_tol`` towards ``direction``."""
    out = ulps_out(b, ulps, direction)
    with np.errstate(over="ignore", invalid="ignore"):
        return np.where(np.isfinite(out), out + np.sign(direction) * abs_tol, out)


@dataclass
class Outcome:
    """Counts of one comparison (for the report) and the masks."""

    n: int
    codac_unsound: int
    skipped: int
    tighter: np.ndarray  # ours strictly inside Codac's beyond the tolerance
    wider: np.ndarray  # ours wider than Codac's beyond the tolerance


def compare(
    name: str,
    lo: np.ndarray,
    hi: np.ndarray,
    ref_lo: np.ndarray,
    ref_hi: np.ndarray,
    feasible: np.ndarray,
    *,
    ulps: int = 4,
    abs_tol=0.0,
    contain_tol=None,
    looser: np.ndarray | None = None,
    wider_ok: np.ndarray | None = None,
) -> Outcome:
    """Checks (1)-(3) for results ``[lo, hi]`` against Codac's ``[ref_lo, ref_hi]``.

    ``feasible`` (m, n): sampled feasible values per case (NaN: none). ``abs_tol``:
    absolute rounding tolerance (per case) of both checks; ``contain_tol``
    (default ``abs_tol``): of check (2) only, where Codac's own rounding is coarser.
    ``looser``: the cases of a documented class where Codac is looser than ours (check
    (2) is skipped there; (3) still holds); ``wider_ok``: the cases of a documented
    class where ours is deliberately wider (check (3) skipped). Asserts, and returns
    the counts."""
    lo, hi = np.broadcast_to(lo, ref_lo.shape), np.broadcast_to(hi, ref_lo.shape)
    f = np.asarray(feasible, dtype=float)
    inside = np.isnan(f) | ((lo <= f) & (f <= hi))
    missed = ~inside.all(axis=0)
    assert not missed.any(), _show(name, "loses feasible points", missed, lo, hi, ref_lo, ref_hi)
    ref_sound = (np.isnan(f) | ((ref_lo <= f) & (f <= ref_hi))).all(axis=0)
    abs_tol = np.broadcast_to(np.asarray(abs_tol, dtype=float), lo.shape)
    tol2 = abs_tol if contain_tol is None else np.broadcast_to(contain_tol, lo.shape)
    looser = np.zeros(lo.shape, bool) if looser is None else np.asarray(looser)
    ours_e, ref_e = ~(lo <= hi), ~(ref_lo <= ref_hi)
    with np.errstate(invalid="ignore"):
        contains = ref_e | (
            ~ours_e
            & (lo <= _widen(ref_lo, ulps, tol2, math.inf))
            & (hi >= _widen(ref_hi, ulps, tol2, -math.inf))
        )
        no_wider = ours_e | (
            ~ref_e
            & (lo >= _widen(ref_lo, ulps, abs_tol, -math.inf))
            & (hi <= _widen(ref_hi, ulps, abs_tol, math.inf))
        )
    bad2 = ref_sound & ~looser & ~contains
    wider_ok = np.zeros(lo.shape, bool) if wider_ok is None else np.asarray(wider_ok)
    bad3 = ref_sound & ~wider_ok & ~no_wider
    assert not bad2.any(), _show(name, "is tighter than Codac", bad2, lo, hi, ref_lo, ref_hi)
    assert not bad3.any(), _show(name, "is wider than Codac", bad3, lo, hi, ref_lo, ref_hi)
    skipped = int(((looser | wider_ok) & ref_sound).sum())
    return Outcome(lo.size, int((~ref_sound).sum()), skipped, ~contains, ~no_wider)


def _show(name, what, mask, lo, hi, ref_lo, ref_hi) -> str:
    i = np.flatnonzero(mask)[:3]
    rows = [
        f"  case {k}: ours [{lo[k]!r}, {hi[k]!r}] codac [{ref_lo[k]!r}, {ref_hi[k]!r}]" for k in i
    ]
    return f"{name} {what} in {int(mask.sum())} cases:\n" + "\n".join(rows)


def align_to(ref_lo: np.ndarray, ref_hi: np.ndarray, lo: np.ndarray, hi: np.ndarray):
    """Codac's angle interval shifted by the multiple of 2*pi that brings it next to
    ours (angles are compared modulo 2*pi); returns the shifted ends (rounded outward)
    and the shift."""
    with np.errstate(invalid="ignore"):
        mo = np.where(np.isfinite(lo + hi), 0.5 * (lo + hi), 0.0)
        mr = np.where(np.isfinite(ref_lo + ref_hi), 0.5 * (ref_lo + ref_hi), 0.0)
    k = np.round((mo - mr) / TAU)
    k = np.where(np.isfinite(k), k, 0.0)
    shift = k * TAU
    return np.nextafter(ref_lo + shift, -math.inf), np.nextafter(ref_hi + shift, math.inf), shift
