"""Scalar fast path of the cooperative contraction for one box (the daemon's case, one
robot's latest pose): the range-bearing contractor to peers (ekf-vs-cp.txt §2.4, the
cooperative constraints of eq. (5); ``localization.contractors.contract_range_bearing``
over ``localization.polar.contract_polar``) on Python floats instead of numpy arrays.

:func:`contract_range_bearing` is one pass of ``polar.contract_polar`` fused into one
function on bare floats over ``localization.polar_scalar``, which holds the operations
of ``localization.interval_scalar`` on separate interval ends (meets of sums and
differences, products by cos and sin, sqr and its backward form, backward
multiplication, cos and sin sharing their argument reduction, bearing, the angle meet,
the quadrant cone), all with the same outward rounding (one ``math.nextafter`` per
computed bound, libm's periodic functions widened by ``TRANS_MARGIN``, tan by
``_TAN_MARGIN``). Checks that are provably idle here (emptiness of operands already
met, NaN of products of finite numbers) are left out, and cos, sin and squares are not
recomputed when their operand kept its values. The boxes are the same bits as the
op-by-op formulation's (``tests/cp_scalar_ref.py``, the code up to e943582), so the
array path's up to libm's last bit (math.cos may differ from numpy's cos by an ulp, far
inside the margin), and as sound.

The fast path covers the common case only: finite boxes within +-1e100 (so no bound
overflows), narrow angle meets, and no interval proven empty along the way. Anything
else raises :class:`Fallback`, and the caller (``SlidingWindowCP.relative``) runs the
array path, which handles every case; the fallback decides nothing by itself, so the
results never depend on which path ran beyond libm's rounding.
``tests/test_cp_scalar_bits.py`` checks the path against the op-by-op formulation bit for
bit, ``tests/test_cp_scalar.py`` against the array path and sampled feasible points.
"""

from __future__ import annotations

import math

from localization.interval_scalar import (
    _INF,
    Fallback,
    Iv,
    _e,
    _nx,
    add,
    cos,
    div,
    mul,
    sin,
    sinc_half,
    sub,
)
from localization.polar_scalar import (
    bearing_f,
    bwd_mul_f,
    bwd_sqr_f,
    cone_f,
    cos_sin_f,
    meet_add_f,
    meet_angle_f,
    meet_polar_f,
    meet_sub_f,
    sqr_f,
)

_BIG = 1e100  # bounds beyond: Fallback (squares and products then stay finite)


def contract_range_bearing(
    xi: Iv, yi: Iv, thi: Iv, xj: Iv, yj: Iv, rho: Iv, beta: Iv
) -> tuple[Iv, Iv, Iv, Iv, Iv, Iv, Iv]:
    """``contractors.contract_range_bearing`` (one polar pass) for one box: the same
    bits as ``tests/cp_scalar_ref.py``'s op-by-op formulation; :class:`Fallback` on an
    empty, unbounded or NaN operand, a bound beyond +-1e100, or an empty result."""
    xil, xih = xi
    yil, yih = yi
    tl, th = thi
    xjl, xjh = xj
    yjl, yjh = yj
    rl, rh = rho
    bl, bh = beta
    big = _BIG
    if not (
        -big <= xil <= xih <= big
        and -big <= yil <= yih <= big
        and -big <= tl <= th <= big
        and -big <= xjl <= xjh <= big
        and -big <= yjl <= yjh <= big
        and -big <= rl <= rh <= big
        and -big <= bl <= bh <= big
    ):
        raise Fallback
    nx, inf = _nx, _INF
    rl = rl if rl > 0.0 else 0.0  # rho >= 0 (a range)
    if not rl <= rh:
        raise Fallback
    # polar.contract_polar(xj - xi, yj - yi, rho, thi + beta)
    dxl, dxh = nx(xjl - xih, -inf), nx(xjh - xil, inf)
    dyl, dyh = nx(yjl - yih, -inf), nx(yjh - yil, inf)
    al, ah = nx(tl + bl, -inf), nx(th + bh, inf)
    cs = cos_sin_f(al, ah)
    dxl, dxh, dyl, dyh = meet_polar_f(dxl, dxh, dyl, dyh, rl, rh, cs)
    # r2 = rho^2 & (dx^2 + dy^2); dx, dy, rho backward through the squares
    ql, qh = sqr_f(rl, rh)
    xsl, xsh = sqr_f(dxl, dxh)
    ysl, ysh = sqr_f(dyl, dyh)
    r2l, r2h = meet_add_f(ql, qh, xsl, xsh, ysl, ysh)
    ndxl, ndxh = bwd_sqr_f(*meet_sub_f(xsl, xsh, r2l, r2h, ysl, ysh), dxl, dxh)
    if ndxl != dxl or ndxh != dxh:  # x^2 depends on the values only
        dxl, dxh = ndxl, ndxh
        xsl, xsh = sqr_f(dxl, dxh)
    dyl, dyh = bwd_sqr_f(*meet_sub_f(ysl, ysh, r2l, r2h, xsl, xsh), dyl, dyh)
    rl, rh = bwd_sqr_f(r2l, r2h, rl, rh)
    if not (rl <= 0.0 <= rh and dxl <= 0.0 <= dxh and dyl <= 0.0 <= dyh):
        b0, b1 = bearing_f(dyl, dyh, dxl, dxh)
        nal, nah = meet_angle_f(al, ah, b0, b1, nx(ah - al, inf), nx(b1 - b0, inf))
        if not nal <= nah:
            raise Fallback
        if nal != al or nah != ah:  # cos and sin depend on the values only
            al, ah = nal, nah
            cs = cos_sin_f(al, ah)
    dxl, dxh, dyl, dyh = cone_f(dxl, dxh, dyl, dyh, al, ah)
    dxl, dxh, dyl, dyh = meet_polar_f(dxl, dxh, dyl, dyh, rl, rh, cs)
    rl, rh = bwd_mul_f(dxl, dxh, rl, rh, cs[0], cs[1])
    rl, rh = bwd_mul_f(dyl, dyh, rl, rh, cs[2], cs[3])
    # back to the operands: thi, beta from alpha; xi, yi, xj, yj from dx, dy
    tl, th = meet_sub_f(tl, th, al, ah, bl, bh)
    bl, bh = meet_sub_f(bl, bh, al, ah, tl, th)
    xil, xih = meet_sub_f(xil, xih, xjl, xjh, dxl, dxh)
    yil, yih = meet_sub_f(yil, yih, yjl, yjh, dyl, dyh)
    xjl, xjh = meet_add_f(xjl, xjh, xil, xih, dxl, dxh)
    yjl, yjh = meet_add_f(yjl, yjh, yil, yih, dyl, dyh)
    return (xil, xih), (yil, yih), (tl, th), (xjl, xjh), (yjl, yjh), (rl, rh), (bl, bh)


def _width(a: Iv) -> float:
    return _nx(a[1] - a[0], _INF)


def relative_fixpoint(
    own: tuple[Iv, Iv, Iv], peers: list[tuple[Iv, Iv, Iv, Iv]], tol: float, max_iter: int
) -> tuple[Iv, Iv, Iv]:
    """``contractors.fixpoint`` of the range-bearing contractor of one box ``own`` =
    (x, y, theta) against every peer (peer x, peer y, rho, beta): each peer contracts its
    own copy of the box, all passes stop together (the largest relative shrink over every
    peer's intervals), and the box is the meet of the copies. Finite bounds only;
    :class:`Fallback` otherwise or on any empty."""
    for iv in own:
        if not (math.isfinite(iv[0]) and math.isfinite(iv[1])) or _e(iv):
            raise Fallback
    cur = []
    for p in peers:
        for iv in p:
            if not (math.isfinite(iv[0]) and math.isfinite(iv[1])) or _e(iv):
                raise Fallback
        cur.append((*own, *p))
    for _ in range(max_iter):
        new = [contract_range_bearing(*c) for c in cur]
        shrink = 0.0
        for c, n in zip(cur, new, strict=True):
            for a, b in zip(c, n, strict=True):
                wa = _width(a)
                rel = (wa - _width(b)) / max(wa, 1e-12)
                if rel > shrink:
                    shrink = rel
        cur = new
        if shrink <= tol:
            break
    out = []
    for i in range(3):
        lo = max(c[i][0] for c in cur)
        hi = min(c[i][1] for c in cur)
        if not lo <= hi:
            raise Fallback
        out.append((lo, hi))
    return out[0], out[1], out[2]


def odometry_displacement(
    th0: Iv, th1: Iv, dsr: Iv, dsl: Iv, e: Iv, kappa: float, chord: bool
) -> tuple[Iv, Iv, Iv]:
    """``contractors.odometry_displacement`` (eq. (1)-(2) forward) for one step: finite
    non-empty operands, :class:`Fallback` otherwise."""
    for iv in (th0, th1, dsr, dsl, e):
        if not (math.isfinite(iv[0]) and math.isfinite(iv[1])) or _e(iv):
            raise Fallback
    ds = mul(add(dsr, dsl), (0.5, 0.5))
    return displacement_dth(th0, th1, ds, div(sub(dsr, dsl), e), kappa, chord)


def displacement_dth(
    th0: Iv, th1: Iv, ds: Iv, dth: Iv, kappa: float, chord: bool
) -> tuple[Iv, Iv, Iv]:
    """eq. (2) forward from finite non-empty headings ``th0``, ``th1`` and the step's
    wheel terms of eq. (1), ``ds`` = (dSr + dSl)/2 and ``dth`` = (dSr - dSl)/e:
    (dx, dy, dtheta), :class:`Fallback` on an empty or unbounded result. The meets,
    sums and products by the point ``kappa`` written out (the same operations as
    meet_ne, add, sub and mul: one ``nextafter`` per bound)."""
    a0, b0 = th0
    a1, b1 = th1
    # dth = dth & (th1 - th0)
    lo, hi = _nx(a1 - b0, -_INF), _nx(b1 - a0, _INF)
    dl = dth[0] if dth[0] > lo else lo
    dh = dth[1] if dth[1] < hi else hi
    if not dl <= dh:
        raise Fallback
    # phi = (th0 + dth * kappa) & (th1 - dth * (1 - kappa))
    k0, k1 = dl * kappa, dh * kappa
    m0, m1 = (k0, k1) if k0 <= k1 else (k1, k0)
    u = 1.0 - kappa
    k0, k1 = dl * u, dh * u
    n0, n1 = (k0, k1) if k0 <= k1 else (k1, k0)
    lo = _nx(a0 + _nx(m0, -_INF), -_INF)
    hi = _nx(b0 + _nx(m1, _INF), _INF)
    lo2 = _nx(a1 - _nx(n1, _INF), -_INF)
    hi2 = _nx(b1 - _nx(n0, -_INF), _INF)
    if lo2 > lo:
        lo = lo2
    if hi2 < hi:
        hi = hi2
    if not lo <= hi:
        raise Fallback
    phi = (lo, hi)
    d = (dl, dh)
    length = mul(ds, sinc_half(d)) if chord else ds
    if not (math.isfinite(length[0]) and math.isfinite(length[1])):
        raise Fallback
    return mul(length, cos(phi)), mul(length, sin(phi)), d


def displacement(th0: Iv, th1: Iv, ds: Iv, dth: Iv, kappa: float, chord: bool) -> tuple[Iv, Iv]:
    """:func:`displacement_dth` without dtheta: the (dx, dy) of a window step."""
    dx, dy, _ = displacement_dth(th0, th1, ds, dth, kappa, chord)
    return dx, dy
