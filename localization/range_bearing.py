"""Range-bearing observations for the real-robot window solver, vectorised over many
observations at once on bare arrays (``localization.interval_kernels``).

An observer O at (ox, oy) with heading oth sees a target A at (ax, ay) at range rho and
bearing beta (in O's frame)::

    ax - ox = rho cos(oth + beta),   ay - oy = rho sin(oth + beta),   rho >= 0

(ekf-vs-cp.txt §2.4's relative measurement; the polar relation of
``localization.polar`` with alpha = oth + beta). It serves three cases:

- a robot sees a known landmark: O is the robot's state box, A the landmark (its
  surveyed position +- its uncertainty);
- a robot sees a peer: A is the peer's last published box, aged (widened by the peer's
  speed bound times the age of the box);
- a robot is seen by a peer: O (with its heading) is the peer's box, A the robot.

:func:`contract_observation` is one pass of the polar relation's projections: the range
(rho^2 = dx^2 + dy^2 forward and backward), the bearing (alpha met with the bearings of
the relative box over every 2 pi branch, so a heading box of any width, or of a known
heading on another branch, is handled), and the products (dx, dy met with rho cos alpha,
rho sin alpha). Unlike ``contract_polar`` it leaves out the cone projection, which only
matters when the range is unknown (here it is always measured). It is sound for any
input box (checked in tests/test_range_bearing.py against sampled feasible points, the
``IV`` contractor ``contractors.contract_range_bearing`` and Codac's ``CtcPolar``).

A heading box of any width is fine: with the whole circle the bearing step leaves it
as it is and the products give the annulus's box; ``localization.cp_rb_solve`` cuts
such a heading into sectors so that the bearing narrows it again.
"""

from __future__ import annotations

import numpy as np

from localization import interval_kernels as K

#: Row order of the (7, 2, m) observation arrays: variable, (lo, hi), observation.
OX, OY, OTH, AX, AY, RHO, BETA = range(7)


def contract_observation(b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One pass over m observations. ``b`` is (7, 2, m): rows OX, OY, OTH, AX, AY, RHO,
    BETA, each (lo, hi); every row non-empty; RHO and BETA finite. Returns the contracted
    array (a new one) and a mask (m,) of observations proven inconsistent (their rows are
    then empty)."""
    out = b.copy()
    ox, oy, oth, ax, ay, rho, beta = (out[i] for i in range(7))
    rho[0] = np.maximum(rho[0], 0.0)  # a range
    dxl, dxh = K.sub(ax[0], ax[1], ox[0], ox[1])
    dyl, dyh = K.sub(ay[0], ay[1], oy[0], oy[1])
    al, ah = K.add(oth[0], oth[1], beta[0], beta[1])
    # Range: rho^2 = dx^2 + dy^2.
    sxl, sxh = K.sqr(dxl, dxh)
    syl, syh = K.sqr(dyl, dyh)
    r2l, r2h = K.add(sxl, sxh, syl, syh)
    pl, ph = K.sqr(rho[0], rho[1])
    r2l, r2h = np.maximum(r2l, pl), np.minimum(r2h, ph)
    ql, qh = K.sqrt(r2l, r2h)
    rho[0], rho[1] = np.maximum(rho[0], ql), np.minimum(rho[1], qh)
    zl, zh = K.sub(r2l, r2h, syl, syh)
    dxl, dxh = K.bwd_sqr(np.maximum(zl, 0.0), zh, dxl, dxh)
    sxl, sxh = K.sqr(dxl, dxh)
    zl, zh = K.sub(r2l, r2h, sxl, sxh)
    dyl, dyh = K.bwd_sqr(np.maximum(zl, 0.0), zh, dyl, dyh)
    # Bearing: alpha = atan2(dy, dx) on some branch, unless the target may coincide
    # with the observer (rho = 0 at the origin holds for every alpha).
    bad = K.empty(dxl, dxh) | K.empty(dyl, dyh) | K.empty(rho[0], rho[1])
    if bad.any():  # keep the kernels' operands non-empty; the result is masked below
        dxl, dxh = np.where(bad, 0.0, dxl), np.where(bad, 1.0, dxh)
        dyl, dyh = np.where(bad, 0.0, dyl), np.where(bad, 1.0, dyh)
    bl, bh = K.bearing(dyl, dyh, dxl, dxh)
    ml, mh = K.meet_angle_k(al, ah, bl, bh)
    free = (rho[0] <= 0.0) & (dxl <= 0.0) & (dxh >= 0.0) & (dyl <= 0.0) & (dyh >= 0.0)
    al, ah = np.where(free, al, ml), np.where(free, ah, mh)
    bad |= K.empty(al, ah)
    if bad.any():
        al, ah = np.where(bad, 0.0, al), np.where(bad, 1.0, ah)
    # Products: dx = rho cos(alpha), dy = rho sin(alpha).
    cl, ch, sl, sh = K.cos_sin(al, ah)
    pxl, pxh = K.mul(rho[0], rho[1], cl, ch)
    pyl, pyh = K.mul(rho[0], rho[1], sl, sh)
    dxl, dxh = np.maximum(dxl, pxl), np.minimum(dxh, pxh)
    dyl, dyh = np.maximum(dyl, pyl), np.minimum(dyh, pyh)
    # Back to the variables.
    for o, a, dl, dh in ((ox, ax, dxl, dxh), (oy, ay, dyl, dyh)):
        nl, nh = K.sub(a[0], a[1], dl, dh)
        o[0], o[1] = np.maximum(o[0], nl), np.minimum(o[1], nh)
        nl, nh = K.add(o[0], o[1], dl, dh)
        a[0], a[1] = np.maximum(a[0], nl), np.minimum(a[1], nh)
    nl, nh = K.sub(al, ah, beta[0], beta[1])
    oth[0], oth[1] = np.maximum(oth[0], nl), np.minimum(oth[1], nh)
    nl, nh = K.sub(al, ah, oth[0], oth[1])
    beta[0], beta[1] = np.maximum(beta[0], nl), np.minimum(beta[1], nh)
    bad |= np.any(K.empty(out[:, 0], out[:, 1]), axis=0)
    if bad.any():
        out[:, 0, bad], out[:, 1, bad] = np.inf, -np.inf
    return out, bad
