"""Forward-backward (HC4-style) contractors for the localization constraints of
ekf-vs-cp.txt, eq. (1)-(2) and the measurement equations of eq. (5).

Every contractor takes interval arrays (:class:`~localization.interval.IV`, any common
broadcast shape: one box, a window of steps, a fleet of robots) and returns them
contracted: no point that satisfies the constraint is ever removed (guaranteed by the
outward-rounded interval operations), and a proven inconsistency yields empties.

Odometry, eq. (1) and (2), with bounded wheel-displacement errors carried by the
intervals ``dsr``, ``dsl`` and the wheel base ``e``::

    dS = (dSr + dSl) / 2,   dth = (dSr - dSl) / e
    x1 = x0 + dS * c * cos(phi),   y1 = y0 + dS * c * sin(phi),   th1 = th0 + dth
    phi = th0 + kappa * dth

kappa = 1, c = 1 is eq. (2) as printed (heading at the end of the step). The default
kappa = 1/2 with c = sin(dth/2)/(dth/2) is the exact chord of a constant-curvature arc,
so a truth that drives arcs satisfies the model exactly (eq. (2) is its first-order
approximation, off by O(dS * dth) per step, which a guaranteed method cannot ignore).

Measurements: GPS position box, gyro heading interval (met modulo 2*pi), range and
bearing between two robots (the polar relation of ``localization.polar``), range to a
known landmark (ranges are >= 0). :func:`fixpoint` repeats a contractor until no
interval shrinks by more than a tolerance.

Headings are real intervals of any width (not wrapped): cos, sin and their backward
projections handle every 2*pi branch, so a heading box of several turns, a half-line or
the whole line is contracted soundly (tests/test_contractors_codac.py checks each
contractor against Codac 2 on such boxes).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from localization.interval import (
    IV,
    bwd_cos,
    bwd_mul,
    bwd_sin,
    bwd_sqr,
    cos,
    meet_angle,
    sin,
    sinc_half,
    sqr,
)
from localization.polar import contract_polar


def odometry_displacement(
    th0: IV, th1: IV, dsr: IV, dsl: IV, e: IV, kappa: float = 0.5, chord: bool = True
) -> tuple[IV, IV, IV]:
    """Forward part of eq. (1)-(2): intervals of (dx, dy, dth) of one step."""
    ds = (dsr + dsl) * 0.5
    dth = (dsr - dsl) / e
    dth = dth & (th1 - th0)
    phi = (th0 + dth * kappa) & (th1 - dth * (1.0 - kappa))
    length = ds * sinc_half(dth) if chord else ds
    return length * cos(phi), length * sin(phi), dth


def contract_odometry(
    x0: IV,
    y0: IV,
    th0: IV,
    x1: IV,
    y1: IV,
    th1: IV,
    dsr: IV,
    dsl: IV,
    e: IV,
    kappa: float = 0.5,
    chord: bool = True,
) -> tuple[IV, IV, IV, IV, IV, IV, IV, IV]:
    """One forward-backward pass over eq. (1)-(2) between poses 0 and 1.

    Returns contracted (x0, y0, th0, x1, y1, th1, dsr, dsl).
    """
    # Forward.
    ds = (dsr + dsl) * 0.5
    dth = (dsr - dsl) / e
    th1 = th1 & (th0 + dth)
    dth = dth & (th1 - th0)
    phi = (th0 + dth * kappa) & (th1 - dth * (1.0 - kappa))
    c = sinc_half(dth) if chord else IV.of(np.ones(np.shape(ds.lo)))
    length = ds * c
    cphi, sphi = cos(phi), sin(phi)
    dx = (length * cphi) & (x1 - x0)
    dy = (length * sphi) & (y1 - y0)
    x1 = x1 & (x0 + dx)
    y1 = y1 & (y0 + dy)
    # Backward.
    x0 = x0 & (x1 - dx)
    y0 = y0 & (y1 - dy)
    length = bwd_mul(dx, length, cphi)
    length = bwd_mul(dy, length, sphi)
    cphi = bwd_mul(dx, cphi, length)
    sphi = bwd_mul(dy, sphi, length)
    phi = bwd_cos(cphi, phi)
    phi = bwd_sin(sphi, phi)
    th0 = th0 & (phi - dth * kappa)
    th1 = th1 & (phi + dth * (1.0 - kappa))
    th0 = th0 & (th1 - dth)
    dth = dth & (th1 - th0)
    ds = bwd_mul(length, ds, c)
    two_ds, e_dth = ds * 2.0, e * dth
    dsr = dsr & (two_ds - dsl) & (dsl + e_dth)
    dsl = dsl & (two_ds - dsr) & (dsr - e_dth)
    return x0, y0, th0, x1, y1, th1, dsr, dsl


def contract_position(x: IV, y: IV, zx: IV, zy: IV) -> tuple[IV, IV]:
    """GPS: the position lies in the measured box ``zx x zy`` (measurement +/- bound)."""
    return x & zx, y & zy


def contract_heading(th: IV, z: IV) -> tuple[IV, IV]:
    """Gyro: the heading lies in ``z`` modulo 2*pi (every branch of ``z`` that meets
    ``th``). Returns the contracted heading and measurement."""
    th = meet_angle(th, z)
    return th, meet_angle(z, th)


def contract_range_bearing(
    xi: IV,
    yi: IV,
    thi: IV,
    xj: IV,
    yj: IV,
    rho: IV,
    beta: IV,
    *,
    polar_tol: float = 1e-3,
    polar_iter: int = 1,
) -> tuple[IV, IV, IV, IV, IV, IV, IV]:
    """Robot i sees robot j at range ``rho`` and bearing ``beta`` (in i's frame):
    ``xj - xi = rho cos(thi + beta)``, ``yj - yi = rho sin(thi + beta)``, rho >= 0: the
    polar relation (``localization.polar``) between the relative position and
    ``thi + beta``.

    ``polar_iter`` > 1 takes the polar relation towards its own fixpoint first
    (:func:`fixpoint` with ``polar_tol``): dx = xj - xi is recomputed from the boxes at
    every call, which forgets what a pass learnt about dx itself, so only then does the
    fixpoint of this contractor reach that of the polar relation with this glue (what
    tests/test_contractors_codac.py checks against Codac). One pass (the default) is
    sound and cheaper; the cooperative CP bench gives the same areas with it.

    Returns contracted (xi, yi, thi, xj, yj, rho, beta).
    """
    rho = rho & IV(np.array(0.0), np.array(np.inf))  # a range
    (dx, dy, rho, alpha), _ = fixpoint(
        contract_polar, [xj - xi, yj - yi, rho, thi + beta], tol=polar_tol, max_iter=polar_iter
    )
    thi = thi & (alpha - beta)
    beta = beta & (alpha - thi)
    xi = xi & (xj - dx)
    yi = yi & (yj - dy)
    xj = xj & (xi + dx)
    yj = yj & (yi + dy)
    return xi, yi, thi, xj, yj, rho, beta


def contract_landmark_range(x: IV, y: IV, lx: IV, ly: IV, rho: IV) -> tuple[IV, IV, IV]:
    """Range to a known landmark: ``(x - lx)^2 + (y - ly)^2 = rho^2``, rho >= 0.

    Returns contracted (x, y, rho)."""
    rho = rho & IV(np.array(0.0), np.array(np.inf))  # a range
    dx, dy = x - lx, y - ly
    r2 = sqr(rho) & (sqr(dx) + sqr(dy))
    dx = bwd_sqr(sqr(dx) & (r2 - sqr(dy)), dx)
    dy = bwd_sqr(sqr(dy) & (r2 - sqr(dx)), dy)
    rho = bwd_sqr(r2, rho)
    return x & (dx + lx), y & (dy + ly), rho


def widths(ivs: Sequence[IV]) -> list[np.ndarray]:
    return [iv.width() for iv in ivs]


def fixpoint(
    contractor: Callable[..., tuple[IV, ...]],
    ivs: Sequence[IV],
    *,
    tol: float = 1e-3,
    max_iter: int = 50,
) -> tuple[tuple[IV, ...], int]:
    """Apply ``contractor(*ivs) -> ivs`` until no interval shrinks by more than ``tol``
    times its previous width (or by 1e-12 absolute), any is empty, or ``max_iter``.

    Returns the contracted intervals and the number of passes made.
    """
    cur = tuple(ivs)
    for it in range(1, max_iter + 1):
        new = tuple(contractor(*cur))
        if any(bool(np.any(iv.is_empty())) for iv in new):
            return new, it
        shrink = 0.0
        for a, b in zip(cur, new, strict=True):
            wa, wb = a.width(), b.width()
            with np.errstate(invalid="ignore"):
                rel = np.where(
                    np.isfinite(wa),
                    (wa - wb) / np.maximum(wa, 1e-12),
                    np.where(np.isfinite(wb), 1.0, 0.0),
                )
            shrink = max(shrink, float(np.max(rel, initial=0.0)))
        cur = new
        if shrink <= tol:
            return cur, it
    return cur, max_iter
