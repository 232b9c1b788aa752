"""The polar relation ``dx = rho cos(alpha)``, ``dy = rho sin(alpha)``: the core of the
range-bearing measurements between robots (ekf-vs-cp.txt §2.4, the cooperative
constraints added to H of eq. (5)), with the relative position (dx, dy), the range rho
and the absolute bearing alpha = heading + measured bearing.

One pass of :func:`contract_polar` meets four projections, each the hull of the exact
projection (up to outward rounding), so the box it converges to matches Codac's minimal
polar contractor (Desrochers & Jaulin 2016, ``codac.CtcPolar``). In pass order:

- products: dx = rho cos(alpha), dy = rho sin(alpha) forward (again at the end, with
  rho backward);
- range: rho^2 = dx^2 + dy^2 forward and backward;
- bearing: alpha met with the bearings of the box dx x dy (``bearing``; + pi where rho
  < 0) over every 2*pi branch of alpha (``meet_angle``);
- cone: dx x dy met with the cone of the directions alpha (+ pi where rho < 0), exactly
  per closed quadrant (there y = x tan t with tan monotone: y in x * [tan a, tan b],
  x in y / [tan a, tan b], except on the quadrant's edges: t = pi/2 holds any y on
  x = 0, t = 0 any x on y = 0), the quadrants' results joined;

rho may have any sign (rho < 0 is the direction alpha + pi); a range measurement meets
rho with [0, inf) first. alpha is a real interval of any width (angles are not wrapped).
"""

from __future__ import annotations

import numpy as np

from localization.interval import (
    HALF_PI,
    IV,
    PI,
    TWO_PI,
    bearing,
    bwd_mul,
    bwd_sqr,
    cos,
    meet_angle,
    sin,
    sqr,
)

_INF = np.inf
_POS = IV(np.array(0.0), np.array(_INF))
# Relative outward margin of libm's tan (a few ulp), far above its error.
_TAN_MARGIN = 1e-14
# (sign of x, sign of y, angle of the quadrant's start / pi) of the four quadrants
_QUADRANTS = ((1.0, 1.0, 0.0), (-1.0, 1.0, 0.5), (-1.0, -1.0, 1.0), (1.0, -1.0, 1.5))


def _tan_q1(t: IV) -> IV:
    """tan over t inside [0, pi/2] (clipped there), rounded outward; inf at pi/2."""
    lo = np.clip(t.lo, 0.0, HALF_PI.lo)
    hi = np.clip(t.hi, 0.0, HALF_PI.hi)
    with np.errstate(over="ignore", invalid="ignore"):
        t_lo = np.maximum(np.tan(lo) * (1.0 - _TAN_MARGIN), 0.0)
        t_hi = np.where(hi >= HALF_PI.lo, _INF, np.tan(hi) * (1.0 + _TAN_MARGIN))
    return IV(t_lo, t_hi)._canon()


def _quadrant_angles(alpha: IV, start: float) -> IV:
    """The angles of ``alpha`` (mod 2*pi) in the closed quadrant [start, start + pi/2]
    (times pi), as an interval inside that quadrant: its whole arc if ``alpha`` meets
    it on more than one 2*pi branch."""
    s_lo, s_hi = start * PI.lo, (start + 0.5) * PI.hi
    arc = IV(np.array(np.nextafter(s_lo, -_INF)), np.array(np.nextafter(s_hi, _INF)))
    a = meet_angle(alpha, arc)
    k = np.round((a.mid() - 0.5 * (s_lo + s_hi)) / TWO_PI)
    k = np.where(np.isfinite(k), k, 0.0)
    r = (a - IV.of(k) * IV(np.array(TWO_PI), np.array(np.nextafter(TWO_PI, _INF)))) & arc
    many = ~(a.width() < np.pi)  # several branches (or unbounded): every angle of it
    empty = a.is_empty()
    return IV(
        np.where(empty, _INF, np.where(many, arc.lo, r.lo)),
        np.where(empty, -_INF, np.where(many, arc.hi, r.hi)),
    )._canon()


def _to_q1(t: IV, start: float) -> IV:
    """A quadrant's angles mapped onto the first quadrant by the reflection that takes
    the quadrant's points (sx x, sy y) to (x, y) >= 0."""
    if start == 0.0:
        return t
    if start == 0.5:
        return PI - t
    if start == 1.0:
        return t - PI
    return -(t - 2.0 * PI)


def _slope_up(prod: IV, tan_t: IV) -> IV:
    """x tan t as the cone needs it: at t = pi/2 (tan inf) the cone holds every y >= 0
    on x = 0, which x * inf (0 * inf = 0 over the reals) would lose."""
    return IV(prod.lo, np.where(tan_t.hi == _INF, _INF, prod.hi))


def _slope_down(quot: IV, tan_t: IV) -> IV:
    """y / tan t as the cone needs it: at t = 0 (tan 0) the cone holds every x >= 0 on
    y = 0, which 0 / [0, b] = {0} and y / [0, 0] = empty would lose."""
    z = tan_t.lo == 0.0
    return IV(np.where(z & (tan_t.hi == 0.0), 0.0, quot.lo), np.where(z, _INF, quot.hi))


def cone(dx: IV, dy: IV, alpha: IV) -> tuple[IV, IV]:
    """(dx, dy) met with the closed cone {r (cos t, sin t): r >= 0, t in alpha mod 2*pi}:
    the hull of the exact meets of each closed quadrant."""
    out_x = out_y = None
    for sx, sy, start in _QUADRANTS:
        px, py = (dx if sx > 0 else -dx) & _POS, (dy if sy > 0 else -dy) & _POS
        if np.all(px.is_empty() | py.is_empty()):
            continue  # the box misses this quadrant everywhere
        ang = _quadrant_angles(alpha, start)
        if np.all(ang.is_empty()):
            continue  # so do the directions
        t = _to_q1(ang, start)
        tan_t = _tan_q1(t)
        qy = py & _slope_up(px * tan_t, tan_t)
        qx = px & _slope_down(py / tan_t, tan_t)
        dead = qx.is_empty() | qy.is_empty() | t.is_empty()
        qx = IV(np.where(dead, _INF, qx.lo), np.where(dead, -_INF, qx.hi))
        qy = IV(np.where(dead, _INF, qy.lo), np.where(dead, -_INF, qy.hi))
        qx, qy = (qx if sx > 0 else -qx), (qy if sy > 0 else -qy)
        out_x = qx if out_x is None else out_x | qx
        out_y = qy if out_y is None else out_y | qy
    if out_x is None:
        return IV.empty(dx.shape), IV.empty(dy.shape)
    return dx & out_x, dy & out_y


def _by_sign(rho: IV, pos: tuple[IV, ...], neg: tuple[IV, ...] | None) -> tuple[IV, ...]:
    """Per case: the rho >= 0 results, the rho <= 0 ones, or their hull."""
    if neg is None:
        return pos
    p_only, n_only = rho.lo >= 0.0, rho.hi <= 0.0
    out = []
    for a, b in zip(pos, neg, strict=True):
        h = a | b
        lo = np.where(p_only, a.lo, np.where(n_only, b.lo, h.lo))
        hi = np.where(p_only, a.hi, np.where(n_only, b.hi, h.hi))
        out.append(IV(lo, hi)._canon())
    return tuple(out)


def contract_polar(dx: IV, dy: IV, rho: IV, alpha: IV) -> tuple[IV, IV, IV, IV]:
    """One pass of the polar relation (module doc). Returns contracted (dx, dy, rho,
    alpha); empties where the relation is proven inconsistent."""
    signed = bool(np.any(rho.lo < 0.0))
    cal, sal = cos(alpha), sin(alpha)
    dx = dx & (rho * cal)
    dy = dy & (rho * sal)
    # Range.
    r2 = sqr(rho) & (sqr(dx) + sqr(dy))
    dx = bwd_sqr(sqr(dx) & (r2 - sqr(dy)), dx)
    dy = bwd_sqr(sqr(dy) & (r2 - sqr(dx)), dy)
    rho = bwd_sqr(r2, rho)
    # Bearing: alpha = atan2(dy, dx) (+ pi for rho < 0); rho = 0 (only at the origin)
    # leaves alpha free.
    b = bearing(dy, dx)
    free = rho.contains(0.0) & dx.contains(0.0) & dy.contains(0.0)
    neg = (meet_angle(alpha, b + PI),) if signed else None
    (a_b,) = _by_sign(rho, (meet_angle(alpha, b),), neg)
    alpha = IV(np.where(free, alpha.lo, a_b.lo), np.where(free, alpha.hi, a_b.hi))._canon()
    # Cone of the directions.
    neg = cone(dx, dy, alpha + PI) if signed else None
    dx, dy = _by_sign(rho, cone(dx, dy, alpha), neg)
    # Products, forward and backward.
    cal, sal = cos(alpha), sin(alpha)
    dx = dx & (rho * cal)
    dy = dy & (rho * sal)
    rho = bwd_mul(dx, rho, cal)
    rho = bwd_mul(dy, rho, sal)
    return dx, dy, rho, alpha
