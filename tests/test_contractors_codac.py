"""The contractors against Codac 2.1.2 on random problems (wrapped, wide, unbounded
headings; relative-position boxes seen under more than pi/2; big turns): (1) every
sampled feasible point is kept; where Codac's result is sound, (2) ours contains and
(3) is no wider than Codac's, both taken at the fixpoint of each (up to rounding).

Codac references: ``CtcPolar`` (its minimal polar contractor) for the polar relation and,
with the same glue, the range-bearing measurement; ``CtcDist`` for the landmark range;
its own 'x = y mod 2*pi' step for the gyro heading; the forward-backward ``CtcInverse``
(no centered form) of eq. (1)-(2) for the odometry.
"""

from __future__ import annotations

import math

import ivgen
import numpy as np
from codac_ref import CODAC, civ, codac, compare, ends
from hypothesis import given, settings
from hypothesis import strategies as st

from localization import contractors as C
from localization.interval import IV
from localization.odometry import motion
from localization.polar import contract_polar

N = 150
SEEDS = st.integers(0, 2**32 - 1)
FEW = settings(max_examples=4, derandomize=True, deadline=None, database=None)
TAU = 2 * math.pi
E = 0.33


def _around(rng, v, lo_exp, hi_exp, unbounded=0.1):
    """Random boxes holding ``v`` (not centred), some with an unbounded end."""
    n = v.shape[0]
    a = 10.0 ** rng.uniform(lo_exp, hi_exp, n) * rng.random(n)
    b = 10.0 ** rng.uniform(lo_exp, hi_exp, n) * rng.random(n)
    lo, hi = v - a, v + b
    unb = rng.random(n) < unbounded
    lo = np.where(unb & (rng.random(n) < 0.5), -np.inf, lo)
    hi = np.where(unb & (rng.random(n) < 0.5), np.inf, hi)
    return lo, hi


def _headings(rng, n):
    """Headings on any 2*pi branch (up to 1e4 turns away)."""
    k = np.where(rng.random(n) < 0.5, 0, rng.integers(-10_000, 10_000, n))
    return rng.uniform(-math.pi, math.pi, n) + TAU * k


_STALLED = [False]  # set when a Codac loop hits its cap short of its fixpoint


def _fix(step, v, max_iter=2000):
    """Codac's contractor ``step`` (list of Codac intervals -> list) to its fixpoint."""
    for _ in range(max_iter):
        old = [(a.lb(), a.ub()) for a in v]
        v = step(v)
        if any(a.is_empty() for a in v):
            return [codac.Interval.empty() for _ in v]
        if [(a.lb(), a.ub()) for a in v] == old:
            return v
    _STALLED[0] = True
    return v


def _ours(contractor, boxes):
    """Our contractor to its fixpoint. Both fixpoint loops run to convergence (some HC4
    cycles approach theirs as a slow geometric series), so that the comparison is of
    the fixpoints, not of how far each loop got."""
    out, _ = C.fixpoint(contractor, [IV.of(lo, hi) for lo, hi in boxes], tol=1e-15, max_iter=2000)
    return out


def _codac(step, boxes):
    """Codac's fixpoint per case, and where its loop stalled short of it (some of its
    HC4 cycles creep, e.g. CtcPolar near the branch cut: check (2) is skipped there)."""
    n = boxes[0][0].shape[0]
    res, stalled = [], np.zeros(n, bool)
    with CODAC():
        for i in range(n):
            _STALLED[0] = False
            res.append(_fix(step, [civ(lo[i], hi[i]) for lo, hi in boxes]))
            stalled[i] = _STALLED[0]
    return [ends([r[j] for r in res]) for j in range(len(boxes))], stalled


def _check_all(names, ours, ref, feasible, looser=None, rel=1e-11, angle=None, rel2=None):
    """(1)-(3) for every variable, up to ``rel`` relative to the case's magnitude (its
    largest finite bound, at least 1), plus the rounding of a reduction of angles as
    large as ``angle``: a few ulp of it, relative, times that magnitude (both libraries
    shift by enclosures of 2*pi*k; a lever arm of length r turns that into r times).
    ``rel2``: a coarser tolerance for check (2) alone, where Codac is less precise."""
    if angle is not None:
        fin = np.where(np.isfinite(angle), angle, 0.0)
        rel = rel + 128 * np.spacing(np.minimum(np.abs(fin), 1e300))
    scale = np.ones(ref[0][0].shape)
    for lo, hi in ref:
        for b in (lo, hi):
            scale = np.maximum(scale, np.where(np.isfinite(b), np.abs(b), 0.0))
    for j, name in enumerate(names):
        lo, hi = ours[j].lo, ours[j].hi
        tol2 = None if rel2 is None else (rel + rel2) * scale
        compare(
            name,
            lo,
            hi,
            *ref[j],
            feasible[j],
            ulps=16,
            abs_tol=rel * scale,
            contain_tol=tol2,
            looser=looser,
        )


def _inside(boxes, values):
    ok = np.ones(values[0].shape, bool)
    for (lo, hi), v in zip(boxes, values, strict=True):
        ok &= (lo <= v) & (v <= hi)
    return ok


def _polar_problem(rng, signed=False):
    rho = np.where(rng.random(N) < 0.5, rng.uniform(0, 10, N), 10.0 ** rng.uniform(-5, 5, N))
    if signed:
        rho = rho * rng.choice([-1.0, 1.0], N)
    alpha = _headings(rng, N)
    dx, dy = rho * np.cos(alpha), rho * np.sin(alpha)
    boxes = [
        _around(rng, dx, -4, 1.5),
        _around(rng, dy, -4, 1.5),
        _around(rng, rho, -4, 1),
        _around(rng, alpha, -4, 1),
    ]
    if not signed:
        boxes[2] = (np.maximum(boxes[2][0], 0.0), boxes[2][1])
    # more feasible points: (rho, alpha) of the boxes whose (dx, dy) falls in theirs
    r, a = ivgen.points(rng, *boxes[2], 8), ivgen.points(rng, *boxes[3], 8)
    with np.errstate(all="ignore"):
        x, y = r * np.cos(a), r * np.sin(a)
    ok = _inside(boxes, [x, y, r, a]) & np.isfinite(x) & np.isfinite(y)
    feas = [
        np.vstack([t[None], np.where(ok, v, np.nan)])
        for t, v in zip([dx, dy, rho, alpha], [x, y, r, a], strict=True)
    ]
    return boxes, feas


# Check (2) against CtcPolar holds up to 1e-7 of the magnitude: near the branch cut
# (alpha ~ pi) its quadrant reductions lose up to ~1e-8 relative where ours is exact to
# rounding (e.g. sup dx = -4.727001467752438: ours -4.727001467751918, Codac
# -4.72700142110618, after 20000 passes: 2000 stop at -4.307).
CTCPOLAR = 1e-7


def _codac_polar(v):
    return list(codac.CtcPolar().contract(*v))


@FEW
@given(SEEDS)
def test_polar_matches_codac_ctcpolar(seed):
    rng = np.random.default_rng(seed)
    boxes, feas = _polar_problem(rng)
    ours = _ours(contract_polar, boxes)
    ref, stalled = _codac(_codac_polar, boxes)
    angle = np.maximum(np.abs(boxes[3][0]), np.abs(boxes[3][1]))
    names = ["dx", "dy", "rho", "alpha"]
    looser = _wide(*boxes[3]) | stalled
    _check_all(names, ours, ref, feas, angle=angle, looser=looser, rel2=CTCPOLAR)


def _wide(lo, hi):
    """Angle boxes wider than pi, where CtcPolar may be looser than ours (never tighter):
    it gets rho only from rho^2 = x^2 + y^2 over the hull of its quadrant pieces, which
    may hold x = 0 (or y = 0) when the directions form two arcs, while ours also divides
    by cos/sin(alpha) (extended division); and beyond 3pi/2 its modulo step takes every
    integer of (theta - quadrant) / 2pi, i.e. two branches of a quadrant even when only
    one meets theta."""
    with np.errstate(invalid="ignore"):
        return ~(hi - lo < math.pi)


@FEW
@given(SEEDS)
def test_polar_with_signed_range_keeps_feasible_points(seed):
    # rho < 0 is the direction alpha + pi (CtcPolar assumes rho >= 0: soundness only)
    rng = np.random.default_rng(seed)
    boxes, feas = _polar_problem(rng, signed=True)
    ours = _ours(contract_polar, boxes)
    for j in range(4):
        f = feas[j]
        assert np.all(np.isnan(f) | ((ours[j].lo <= f) & (f <= ours[j].hi))), j


def _rb_problem(rng):
    """Robot i at (xi, yi, thi) sees j at range rho, bearing beta: position boxes up to
    several times the range (seen under more than pi/2), headings of any width/branch."""
    n = N
    th = _headings(rng, n)
    beta = rng.uniform(-math.pi, math.pi, n)
    rho = 10.0 ** rng.uniform(-1, 1.5, n)
    xi, yi = rng.uniform(-50, 50, n), rng.uniform(-50, 50, n)
    xj, yj = xi + rho * np.cos(th + beta), yi + rho * np.sin(th + beta)
    scale = np.log10(rho)
    boxes = [
        _around(rng, xi, -3, 1 + scale.max()),
        _around(rng, yi, -3, 1 + scale.max()),
        _around(rng, th, -3, 1.3),
        _around(rng, xj, -3, 0.5),
        _around(rng, yj, -3, 0.5),
        _around(rng, rho, -4, 0, unbounded=0.0),
        _around(rng, beta, -4, -1, unbounded=0.0),
    ]
    boxes[5] = (np.maximum(boxes[5][0], 0.0), boxes[5][1])
    return boxes, [xi, yi, th, xj, yj, rho, beta]


def _codac_range_bearing(v):
    xi, yi, thi, xj, yj, rho, beta = v
    dx, dy, alpha = xj - xi, yj - yi, thi + beta
    # like ours, the polar relation to its fixpoint before the glue
    dx, dy, rho, alpha = _fix(_codac_polar, [dx, dy, rho & codac.Interval(0, codac.oo), alpha])
    thi &= alpha - beta
    beta &= alpha - thi
    xi &= xj - dx
    yi &= yj - dy
    xj &= xi + dx
    yj &= yi + dy
    return [xi, yi, thi, xj, yj, rho, beta]


@FEW
@given(SEEDS)
def test_range_bearing_matches_codac_polar_with_the_same_glue(seed):
    rng = np.random.default_rng(seed)
    boxes, truth = _rb_problem(rng)
    ours = _ours(lambda *v: C.contract_range_bearing(*v, polar_tol=1e-15, polar_iter=2000), boxes)
    ref, stalled = _codac(_codac_range_bearing, boxes)
    angle = np.maximum(np.abs(boxes[2][0]), np.abs(boxes[2][1])) + math.pi
    names = ["xi", "yi", "thi", "xj", "yj", "rho", "beta"]
    wide = _wide(boxes[2][0] + boxes[6][0], boxes[2][1] + boxes[6][1])
    feas = [t[None] for t in truth]
    _check_all(names, ours, ref, feas, angle=angle, looser=wide | stalled, rel2=CTCPOLAR)


def test_range_bearing_keeps_the_heading_when_the_relative_box_is_wide():
    # The old contractor cut the true heading -0.9048 out of [-0.906, 2.19] (it wrapped
    # the corner bearings around the centre of a near-pi-wide heading + bearing).
    th, beta = -0.904805981021441, -1.3577471277915887
    box = [
        IV.of(-0.6434500895156426, 0.5123982736057147),
        IV.of(-1.4986783794937466, 3.2889501291238927),
        IV.of(-0.9064640073460549, 2.193535992653945),
        IV.of(-1.5533987079374911, -1.3533987079374905),
        IV.of(0.17831170221938214, 0.3783117022193822),
        IV.of(1.5371258989757917, 1.6371258989757922),
        IV.of(-1.3677471277915885, -1.347747127791588),
    ]
    out, _ = C.fixpoint(C.contract_range_bearing, box, tol=1e-9)
    assert bool(out[2].contains(th)) and bool(out[6].contains(beta))


def _codac_dist(v):
    x, y, lx, ly, rho = v
    return list(codac.CtcDist().contract(x, y, lx, ly, rho))


@FEW
@given(SEEDS)
def test_landmark_range_matches_codac_ctcdist(seed):
    rng = np.random.default_rng(seed)
    p = rng.uniform(-100, 100, (2, N))
    lm = rng.uniform(-100, 100, (2, N))
    rho = np.hypot(*(p - lm))
    boxes = [_around(rng, p[0], -3, 2), _around(rng, p[1], -3, 2), _around(rng, rho, -4, 0.5)]
    lmb = [(lm[0], lm[0]), (lm[1], lm[1])]

    def ours_fn(x, y, r):
        return C.contract_landmark_range(x, y, IV.of(lm[0]), IV.of(lm[1]), r)

    ours = _ours(ours_fn, boxes)
    ref, stalled = _codac(_codac_dist, [boxes[0], boxes[1], *lmb, boxes[2]])
    ref = [ref[0], ref[1], ref[4]]
    feas = [p[0][None], p[1][None], rho[None]]
    _check_all(["x", "y", "rho"], ours, ref, feas, looser=stalled)


def _codac_mod(box: codac.Interval, z: codac.Interval) -> codac.Interval:
    two_pi = 2 * codac.Interval.pi()
    return box & (z + codac.integer((box - z) / two_pi) * two_pi)


@FEW
@given(SEEDS)
def test_gyro_heading_matches_codac_modulo(seed):
    rng = np.random.default_rng(seed)
    th = _headings(rng, N)
    z = th - TAU * rng.integers(-3, 4, N)  # the fix, on another branch
    tb = _around(rng, th, -3, 2)
    zb = (z - 10.0 ** rng.uniform(-3, 0.5, N), z + 10.0 ** rng.uniform(-3, 0.5, N))
    th_c, z_c = C.contract_heading(IV.of(*tb), IV.of(*zb))
    with CODAC():
        ref_t = [_codac_mod(civ(a, b), civ(c, d)) for a, b, c, d in zip(*tb, *zb, strict=True)]
        ref_z = [_codac_mod(civ(c, d), t) for t, c, d in zip(ref_t, *zb, strict=True)]
    tol = 8 * np.spacing(np.maximum(np.abs(th), TAU))
    compare("theta", th_c.lo, th_c.hi, *ends(ref_t), th[None], ulps=8, abs_tol=tol)
    zf = np.where(IV.of(*zb).contains(z), z, np.nan)[None]
    compare("z", z_c.lo, z_c.hi, *ends(ref_z), zf, ulps=8, abs_tol=tol)


def _odometry_problem(rng, kappa, chord):
    """Poses on any heading branch, turns up to ~10 rad in one step (beyond 2*pi), boxes
    of every width (some unbounded); feasible points: the truth, and poses/wheel
    displacements drawn in the start boxes whose image falls in the end boxes."""
    s0 = np.stack([rng.uniform(-100, 100, N), rng.uniform(-100, 100, N), _headings(rng, N)])
    big = rng.random(N) < 0.3
    dsr = np.where(big, rng.uniform(-2, 2, N), rng.uniform(-0.1, 0.3, N))
    dsl = np.where(big, rng.uniform(-2, 2, N), rng.uniform(-0.1, 0.3, N))

    def f(x, y, th, r, l):
        return motion(np.array([x, y, th]), (r, l), E, kappa=kappa, chord=chord)

    s1 = np.stack([f(*s0[:, k], dsr[k], dsl[k]) for k in range(N)], axis=1)
    truth = [s0[0], s0[1], s0[2], s1[0], s1[1], s1[2], dsr, dsl]
    boxes = [_around(rng, t, -3, 1) for t in truth[:6]]
    boxes += [_around(rng, t, -5, -1, unbounded=0.0) for t in truth[6:]]
    pts = [ivgen.points(rng, lo, hi, 4)[2:] for lo, hi in boxes[:3] + boxes[6:]]
    extra = [[] for _ in range(8)]
    for m in range(2):
        p = [q[m] for q in pts]
        fin = np.all([np.isfinite(q) for q in p], axis=0)
        img = np.stack(
            [f(*(q[k] for q in p)) if fin[k] else np.full(3, np.nan) for k in range(N)], axis=1
        )
        vals = [p[0], p[1], p[2], img[0], img[1], img[2], p[3], p[4]]
        ok = fin & _inside(boxes, vals)
        for j in range(8):
            extra[j].append(np.where(ok, vals[j], np.nan))
    feas = [np.vstack([truth[j][None], *extra[j]]) for j in range(8)]
    return boxes, feas


def _codac_odometry(kappa):
    """HC4 (forward-backward, no centered form) of eq. (1)-(2) as written, the angle of
    the move phi = th0 + kappa * dth (th1 itself for kappa = 1, like ours)."""
    x = codac.VectorVar(8)  # x0 y0 th0 x1 y1 th1 dsr dsl
    ds, dth = (x[6] + x[7]) / 2.0, (x[6] - x[7]) / E
    phi = x[5] if kappa == 1.0 else x[2] + kappa * dth
    f = codac.AnalyticFunction(
        [x],
        codac.vec(
            x[3] - x[0] - ds * codac.cos(phi), x[4] - x[1] - ds * codac.sin(phi), x[5] - x[2] - dth
        ),
    )
    ctc = codac.CtcInverse(f, codac.IntervalVector([[0, 0]] * 3), False)

    def step(v):
        box = codac.IntervalVector([[a.lb(), a.ub()] for a in v])
        ctc.contract(box)
        if box.is_empty():
            return [codac.Interval.empty()] * 8
        return [box[j] for j in range(8)]

    return step


ODO = ["x0", "y0", "th0", "x1", "y1", "th1", "dsr", "dsl"]


@FEW
@given(SEEDS, st.sampled_from([1.0, 0.5]))
def test_odometry_no_wider_than_codac_forward_backward(seed, kappa):
    rng = np.random.default_rng(seed)
    boxes, feas = _odometry_problem(rng, kappa, chord=False)
    e = IV.of(E)
    ours = _ours(lambda *v: C.contract_odometry(*v, e, kappa=kappa, chord=False), boxes)
    with CODAC():
        step = _codac_odometry(kappa)
    ref, _ = _codac(step, boxes)
    # (2) waived: our decomposition shares more than Codac's expression tree (phi is met
    # from both ends, th0 + kappa dth and th1 - (1 - kappa) dth; the move length is one
    # node for the x and y equations), so ours is often strictly tighter (sound: (1)).
    _check_all(ODO, ours, ref, feas, looser=np.ones(N, bool), rel=1e-9)


@FEW
@given(SEEDS)
def test_odometry_chord_model_keeps_feasible_points(seed):
    # The exact-arc model (kappa = 1/2, chord factor sin(dth/2)/(dth/2)) has no singular-
    # free natural form for Codac: soundness only, turns beyond 2*pi included.
    rng = np.random.default_rng(seed)
    boxes, feas = _odometry_problem(rng, 0.5, chord=True)
    e = IV.of(E)
    ours = _ours(lambda *v: C.contract_odometry(*v, e), boxes)
    for j in range(8):
        f = feas[j]
        assert np.all(np.isnan(f) | ((ours[j].lo <= f) & (f <= ours[j].hi))), ODO[j]
