"""Random boxes and feasible points for the interval property tests, and the bridge to
Codac 2 (the reference interval library: a test dependency only).

Boxes mix every kind an operation must survive: ordinary, wide, huge (up to 1e300),
tiny (down to 1e-300), denormal, single points, touching or straddling 0, half-lines and
the whole line. Angles add wrapped boxes (2*pi*k far from 0) and boxes wider than a turn.
"""

from __future__ import annotations

import math

import numpy as np

KINDS = ("normal", "wide", "huge", "tiny", "denormal", "point", "zero", "unbounded")
TAU = 2.0 * math.pi


def _mags(rng, n, lo_exp, hi_exp):
    return 10.0 ** rng.uniform(lo_exp, hi_exp, n) * rng.choice([-1.0, 1.0], n)


def boxes(rng: np.random.Generator, n: int, kinds=KINDS) -> tuple[np.ndarray, np.ndarray]:
    """``n`` random intervals (lo, hi), each of a kind drawn from ``kinds``."""
    kind = rng.choice(len(kinds), n)
    lo, hi = np.empty(n), np.empty(n)
    for i, k in enumerate(kinds):
        m = kind == i
        c = int(m.sum())
        if k == "normal":
            a = rng.uniform(-10, 10, c)
            b = a + 10.0 ** rng.uniform(-6, 1, c)
        elif k == "wide":
            a = rng.uniform(-1e3, 1e3, c)
            b = a + rng.uniform(0, 2e3, c)
        elif k == "huge":
            a = _mags(rng, c, 10, 300)
            b = a + np.abs(a) * 10.0 ** rng.uniform(-16, 0.3, c)
        elif k == "tiny":
            a = _mags(rng, c, -300, -5)
            b = a + np.abs(a) * 10.0 ** rng.uniform(-3, 0.5, c)
        elif k == "denormal":
            a = rng.integers(-(2**40), 2**40, c) * 5e-324
            b = a + rng.integers(0, 2**40, c) * 5e-324
        elif k == "point":
            a = b = np.where(rng.random(c) < 0.5, rng.uniform(-5, 5, c), _mags(rng, c, -20, 20))
        elif k == "zero":
            w = 10.0 ** rng.uniform(-8, 2, c)
            side = rng.integers(0, 3, c)  # [0, w], [-w, 0], [-w, w']
            a = np.where(side == 0, 0.0, -w)
            b = np.where(side == 1, 0.0, np.where(side == 0, w, w * rng.uniform(0, 2, c)))
        else:  # unbounded
            a = rng.uniform(-10, 10, c)
            b = a + rng.uniform(0, 10, c)
            side = rng.integers(0, 3, c)
            a = np.where(side != 1, -np.inf, a)
            b = np.where(side != 0, np.inf, b)
        lo[m], hi[m] = np.minimum(a, b), np.maximum(a, b)
    return lo, hi


def angle_boxes(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Heading-like intervals: narrow or wide, near 0 or wrapped far away (2*pi*k with
    |k| up to 1e6), wider than a turn, unbounded, or of any kind of :func:`boxes`."""
    kind = rng.integers(0, 5, n)
    k = np.where(rng.random(n) < 0.5, 0.0, np.round(_mags(rng, n, 0, 6)))
    c = rng.uniform(-math.pi, math.pi, n) + TAU * k
    w = np.where(kind == 0, 10.0 ** rng.uniform(-6, 0, n), rng.uniform(0, 4 * TAU, n))
    lo, hi = c - w * rng.random(n), c + w * rng.random(n)
    blo, bhi = boxes(rng, n)
    lo = np.where(kind == 4, blo, lo)
    hi = np.where(kind == 4, bhi, hi)
    hi = np.where(kind == 3, np.inf, hi)
    return lo, np.maximum(lo, hi)


def points(rng: np.random.Generator, lo: np.ndarray, hi: np.ndarray, m: int) -> np.ndarray:
    """``m`` points of each interval (shape (m, n)): both ends where finite, then
    uniform draws; an unbounded end is stood in for by far finite points."""
    n = lo.shape[0]
    out = np.empty((m, n))
    for r in range(m):
        # rows 0 and 1: the ends, an unbounded one stood in for by a point 1e300 away
        far = np.full(n, 1e300) if r < 2 else 10.0 ** rng.uniform(0, 300, n)
        flo = np.where(
            np.isfinite(lo), lo, np.where(np.isfinite(hi), np.minimum(hi, 0.0), 0.0) - far
        )
        fhi = np.where(np.isfinite(hi), hi, np.maximum(flo, 0.0) + far)
        t = 0.0 if r == 0 else 1.0 if r == 1 else rng.random(n)
        with np.errstate(over="ignore", invalid="ignore"):
            p = flo + (fhi - flo) * t
            p = np.where(np.isfinite(p), p, flo * (1 - t) + fhi * t)
        out[r] = np.clip(p, flo, fhi)
    return out


def grid(pa: np.ndarray, pb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every pairing of the sampled points of two intervals (corners included):
    arrays of shape (m * m, n)."""
    m = pa.shape[0]
    return np.repeat(pa, m, axis=0), np.tile(pb, (m, 1))


def codac_iv(lo: float, hi: float):
    import codac

    if not lo <= hi:
        return codac.Interval.empty()
    return codac.Interval(float(lo), float(hi))


def bounds(iv) -> tuple[float, float]:
    """(lo, hi) of a Codac interval; (inf, -inf) if empty."""
    if iv.is_empty():
        return math.inf, -math.inf
    return iv.lb(), iv.ub()
