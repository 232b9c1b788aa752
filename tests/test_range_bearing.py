"""The bare-array interval kernels and the range-bearing observation contractor of the
real-robot CP (localization/interval_kernels.py, localization/range_bearing.py).

Kernels: the same bounds as the ``IV`` operation each mirrors, on random boxes of every
kind the kernel's precondition admits, and every sampled point inside. Contractor: on
random observations (relative boxes seen under any angle, headings of any width and
branch, unbounded positions) (1) every sampled feasible point is kept, (2) it contains
the ``IV`` range-bearing contractor's fixpoint and (3) Codac 2.1.2's (``CtcPolar`` with
the same glue) where Codac's is sound. It is not compared for tightness: it leaves out
the cone projection of the polar relation, which only matters for an unknown range.
"""

from __future__ import annotations

import math

import ivgen
import numpy as np
from codac_ref import CODAC, civ, codac, ends
from hypothesis import given, settings
from hypothesis import strategies as st

from localization import contractors as C
from localization import interval as I
from localization import interval_kernels as K
from localization.interval import IV
from localization.range_bearing import contract_observation

N = 300
SEEDS = st.integers(0, 2**32 - 1)
FEW = settings(max_examples=5, derandomize=True, deadline=None, database=None)
TAU = 2 * math.pi
FINITE = ("normal", "wide", "huge", "tiny", "denormal", "point", "zero")


def _same(name, ours, ref):
    lo, hi = ours
    assert np.array_equal(lo, ref.lo) and np.array_equal(hi, ref.hi), name


def _holds(name, ours, pts):
    lo, hi = ours
    ok = np.isnan(pts) | ((lo <= pts) & (pts <= hi))
    assert ok.all(), f"{name} loses points: {np.flatnonzero(~ok.all(axis=0))[:5]}"


@FEW
@given(SEEDS)
def test_kernels_match_the_interval_operations(seed):
    rng = np.random.default_rng(seed)
    al, ah = ivgen.boxes(rng, N)
    bl, bh = ivgen.boxes(rng, N)
    a, b = IV.of(al, ah), IV.of(bl, bh)
    pa, pb = ivgen.points(rng, al, ah, 6), ivgen.points(rng, bl, bh, 6)
    with np.errstate(all="ignore"):
        _same("add", K.add(al, ah, bl, bh), a + b)
        _same("sub", K.sub(al, ah, bl, bh), a - b)
        _same("sqr", K.sqr(al, ah), I.sqr(a))
        _same("bearing", K.bearing(al, ah, bl, bh), I.bearing(a, b))
        _holds("add", K.add(al, ah, bl, bh), np.where(np.isfinite(pa + pb), pa + pb, np.nan))
        pos = ah >= 0
        sq = K.sqrt(al[pos], ah[pos])
        _same("sqrt", sq, I.sqrt(a[pos]))
    fl, fh = ivgen.boxes(rng, N, FINITE)
    gl, gh = ivgen.boxes(rng, N, FINITE)
    with np.errstate(all="ignore"):
        ok = (
            np.isfinite(fl * gl)
            & np.isfinite(fh * gh)
            & np.isfinite(fl * gh)
            & np.isfinite(fh * gl)
        )
        _same(
            "mul",
            K.mul(fl[ok], fh[ok], gl[ok], gh[ok]),
            IV.of(fl[ok], fh[ok]) * IV.of(gl[ok], gh[ok]),
        )


@FEW
@given(SEEDS)
def test_periodic_kernels_match_and_keep_points(seed):
    rng = np.random.default_rng(seed)
    lo, hi = ivgen.angle_boxes(rng, N)
    x, px = IV.of(lo, hi), ivgen.points(rng, lo, hi, 6)
    cl, ch, sl, sh = K.cos_sin(lo, hi)
    _same("cos", (cl, ch), I.cos(x))
    _same("sin", (sl, sh), I.sin(x))
    _holds("cos", (cl, ch), np.cos(px))
    _holds("sin", (sl, sh), np.sin(px))
    zl, zh = ivgen.angle_boxes(rng, N)
    ref = I.meet_angle(x, IV.of(zl, zh))
    got = K.meet_angle_k(lo, hi, zl, zh)
    assert np.all((got[0] == ref.lo) & (got[1] == ref.hi) | (~(got[0] <= got[1]) & ref.is_empty()))
    # bwd_sqr against the IV projection, z >= 0
    z_lo = rng.uniform(0.0, 7.0, N)
    z_hi = z_lo + rng.uniform(0.0, 3.0, N)
    bl, bh = ivgen.boxes(rng, N, FINITE)
    ref = I.bwd_sqr(IV.of(z_lo, z_hi), IV.of(bl, bh))
    got = K.bwd_sqr(z_lo, z_hi, bl, bh)
    assert np.all(
        ((got[0] == ref.lo) & (got[1] == ref.hi)) | (~(got[0] <= got[1]) & ref.is_empty())
    )


def _around(rng, v, lo_exp, hi_exp, unbounded=0.0):
    n = v.shape[0]
    a = 10.0 ** rng.uniform(lo_exp, hi_exp, n) * rng.random(n)
    b = 10.0 ** rng.uniform(lo_exp, hi_exp, n) * rng.random(n)
    lo, hi = v - a, v + b
    unb = rng.random(n) < unbounded
    lo = np.where(unb & (rng.random(n) < 0.5), -np.inf, lo)
    hi = np.where(unb & (rng.random(n) < 0.5), np.inf, hi)
    return lo, hi


def _problem(rng):
    """An observer (x, y, heading on any branch, up to 40 turns wide) sees a target at
    range rho (10 cm to 30 m) and bearing beta; boxes around the truth of every size."""
    th = rng.uniform(-math.pi, math.pi, N) + TAU * np.where(
        rng.random(N) < 0.5, 0, rng.integers(-1000, 1000, N)
    )
    beta = rng.uniform(-math.pi, math.pi, N)
    rho = 10.0 ** rng.uniform(-1, 1.5, N)
    ox, oy = rng.uniform(-20, 20, N), rng.uniform(-20, 20, N)
    ax, ay = ox + rho * np.cos(th + beta), oy + rho * np.sin(th + beta)
    boxes = [
        _around(rng, ox, -3, 1.7, 0.1),
        _around(rng, oy, -3, 1.7, 0.1),
        _around(rng, th, -3, 2.4, 0.05),
        _around(rng, ax, -3, 1.0, 0.05),
        _around(rng, ay, -3, 1.0, 0.05),
        _around(rng, rho, -3, 0.3),
        _around(rng, beta, -4, -0.5),
    ]
    boxes[5] = (np.maximum(boxes[5][0], 0.0), boxes[5][1])
    return boxes, [ox, oy, th, ax, ay, rho, beta]


def _ours(boxes, passes=60):
    b = np.array([[lo, hi] for lo, hi in boxes])
    for _ in range(passes):
        b, bad = contract_observation(b)
    return b


def _feasible(rng, boxes, truth, k=6):
    """The truth plus points sampled in the boxes that satisfy the relation (the target
    placed from a sampled observer, heading, range and bearing)."""
    pts = [np.vstack([t[None]]) for t in truth]
    samp = [ivgen.points(rng, lo, hi, k) for lo, hi in boxes]
    ox, oy, th, _, _, rho, beta = samp
    with np.errstate(all="ignore"):
        ax, ay = ox + rho * np.cos(th + beta), oy + rho * np.sin(th + beta)
    vals = [ox, oy, th, ax, ay, rho, beta]
    ok = np.ones(ox.shape, bool)
    for (lo, hi), v in zip(boxes, vals, strict=True):
        ok &= np.isfinite(v) & (lo <= v) & (v <= hi)
    return [np.vstack([p, np.where(ok, v, np.nan)]) for p, v in zip(pts, vals, strict=True)]


@FEW
@given(SEEDS)
def test_observation_keeps_feasible_points_and_contains_the_iv_contractor(seed):
    rng = np.random.default_rng(seed)
    boxes, truth = _problem(rng)
    out = _ours(boxes)
    feas = _feasible(rng, boxes, truth)
    names = ["ox", "oy", "oth", "ax", "ay", "rho", "beta"]
    for j, name in enumerate(names):
        f = feas[j]
        inside = np.isnan(f) | ((out[j, 0] <= f) & (f <= out[j, 1]))
        assert inside.all(), (
            f"{name} loses feasible points in {np.flatnonzero(~inside.all(axis=0))[:5]}"
        )
    ref, _ = C.fixpoint(
        C.contract_range_bearing, [IV.of(lo, hi) for lo, hi in boxes], tol=1e-12, max_iter=60
    )
    for j, name in enumerate(names):
        r = ref[j]
        tol = 1e-9 * np.maximum(
            1.0,
            np.where(np.isfinite(r.lo), np.abs(r.lo), 0)
            + np.where(np.isfinite(r.hi), np.abs(r.hi), 0),
        )
        with np.errstate(invalid="ignore"):
            ok = r.is_empty() | ((out[j, 0] <= r.lo + tol) & (out[j, 1] >= r.hi - tol))
        assert ok.all(), f"{name}: narrower than the IV contractor in {np.flatnonzero(~ok)[:5]}"


def _codac_step(v):
    ox, oy, oth, ax, ay, rho, beta = v
    dx, dy, alpha = ax - ox, ay - oy, oth + beta
    dx, dy, rho, alpha = codac.CtcPolar().contract(dx, dy, rho & codac.Interval(0, codac.oo), alpha)
    oth &= alpha - beta
    beta &= alpha - oth
    ox &= ax - dx
    oy &= ay - dy
    ax &= ox + dx
    ay &= oy + dy
    return [ox, oy, oth, ax, ay, rho, beta]


@FEW
@given(SEEDS)
def test_observation_contains_codac_polar_with_the_same_glue(seed):
    rng = np.random.default_rng(seed)
    boxes, truth = _problem(rng)
    n = 80  # Codac runs case by case
    boxes = [(lo[:n], hi[:n]) for lo, hi in boxes]
    truth = [t[:n] for t in truth]
    out = _ours(boxes)
    res = []
    with CODAC():
        for i in range(n):
            v = [civ(lo[i], hi[i]) for lo, hi in boxes]
            for _ in range(60):
                v = _codac_step(v)
            res.append(v)
    for j in range(7):
        rlo, rhi = ends([r[j] for r in res])
        sound = np.ones(n, bool)
        for t, (lo, hi) in zip(truth, [ends([r[k] for r in res]) for k in range(7)], strict=True):
            sound &= (lo <= t) & (t <= hi)
        tol = 1e-7 * np.maximum(
            1.0,
            np.where(np.isfinite(rlo), np.abs(rlo), 0) + np.where(np.isfinite(rhi), np.abs(rhi), 0),
        )
        with np.errstate(invalid="ignore"):
            ok = ~sound | ~(rlo <= rhi) | ((out[j, 0] <= rlo + tol) & (out[j, 1] >= rhi - tol))
        assert ok.all(), f"row {j}: narrower than Codac in {np.flatnonzero(~ok)[:5]}"
        assert np.all((out[j, 0] <= truth[j]) & (truth[j] <= out[j, 1])), j


def test_unknown_heading_gives_the_annulus_box_and_a_bearing_narrows_a_sector():
    # Observer heading unknown (the whole line): a landmark 5 m away at bearing 0.3
    # only says "within the annulus" -> the box of the disc around the landmark.
    lm = (3.0, 4.0)
    b = np.array([[[-np.inf], [np.inf]], [[-np.inf], [np.inf]], [[-np.inf], [np.inf]],
                  [[lm[0]], [lm[0]]], [[lm[1]], [lm[1]]], [[4.9], [5.1]], [[0.29], [0.31]]])  # fmt: skip
    out, bad = contract_observation(b)
    assert not bad[0]
    assert out[0, 0, 0] >= lm[0] - 5.1 - 1e-9 and out[0, 1, 0] <= lm[0] + 5.1 + 1e-9
    assert np.isneginf(out[2, 0, 0]) and np.isposinf(out[2, 1, 0])
    # The same with the heading confined to one sector of the circle (truth 0.7): the
    # position becomes a small box and the heading narrows inside the sector.
    th, rho, beta = 0.7, 5.0, 0.3
    ox, oy = lm[0] - rho * math.cos(th + beta), lm[1] - rho * math.sin(th + beta)
    b[0] = [[ox - 3], [ox + 3]]
    b[1] = [[oy - 3], [oy + 3]]
    b[2] = [[0.5], [0.9]]
    for _ in range(20):
        b, bad = contract_observation(b)
    assert not bad[0]
    assert b[0, 0, 0] <= ox <= b[0, 1, 0] and b[1, 0, 0] <= oy <= b[1, 1, 0]
    assert b[0, 1, 0] - b[0, 0, 0] < 2.2 and b[1, 1, 0] - b[1, 0, 0] < 2.2


def test_inconsistent_observation_is_empty():
    b = np.array([[[0.0], [1.0]], [[0.0], [1.0]], [[0.0], [0.1]], [[10.0], [10.0]],
                  [[0.0], [0.0]], [[2.0], [3.0]], [[0.0], [0.01]]])  # fmt: skip
    out, bad = contract_observation(b)
    assert bad[0] and not (out[0, 0, 0] <= out[0, 1, 0])
