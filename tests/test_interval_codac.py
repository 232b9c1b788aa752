"""The interval operations against Codac 2.1.2 on random boxes of every kind (wide, huge,
tiny, denormal, points, around 0, unbounded, wrapped angles): (1) every sampled
feasible point is kept, (2) ours contains Codac's result and (3) is no wider, up to
rounding, where Codac's is sound (see tests/codac_ref.py). Derandomized hypothesis
draws the seeds; each example checks a batch of boxes.
"""

from __future__ import annotations

import math

import ivgen
import numpy as np
from codac_ref import CODAC, align_to, civ, civs, codac, compare, ends
from hypothesis import given, settings
from hypothesis import strategies as st

from localization import interval as I
from localization.interval import IV

N = 300  # boxes per example
SEEDS = st.integers(0, 2**32 - 1)
FEW = settings(max_examples=6, derandomize=True, deadline=None, database=None)
TM = I.TRANS_MARGIN
TMR = TM + 1e-15  # TRANS_MARGIN and a few ulp of values below 2 pi
TAU = 2 * math.pi


def _pair(rng, kinds=ivgen.KINDS):
    a, b = ivgen.boxes(rng, N, kinds)
    return IV.of(a, b), ivgen.points(rng, a, b, 6)


@FEW
@given(SEEDS)
def test_arithmetic_matches_codac(seed):
    rng = np.random.default_rng(seed)
    (x, px), (y, py) = _pair(rng), _pair(rng)
    cx, cy = civs(x), civs(y)
    pairs = list(zip(cx, cy, strict=True))
    with np.errstate(all="ignore"), CODAC():
        cases = {
            "+": (x + y, [a + b for a, b in pairs], px + py),
            "-": (x - y, [a - b for a, b in pairs], px - py),
            "*": (x * y, [a * b for a, b in pairs], px * py),
            "/": (x / y, [a / b for a, b in pairs], np.where(py != 0, px / py, np.nan)),
        }
    for name, (ours, ref, feas) in cases.items():
        feas = np.where(np.isfinite(feas), feas, np.nan)  # overflowed samples say nothing
        compare(name, ours.lo, ours.hi, *ends(ref), feas)


@FEW
@given(SEEDS)
def test_sqr_sqrt_match_codac(seed):
    rng = np.random.default_rng(seed)
    x, px = _pair(rng)
    cx = civs(x)
    with np.errstate(all="ignore"):
        sq = np.where(np.isfinite(px * px), px * px, np.nan)
        rt = np.where(px >= 0, np.sqrt(np.abs(px)), np.nan)
    with CODAC():
        ref_sq, ref_rt = [codac.sqr(a) for a in cx], [codac.sqrt(a) for a in cx]
    compare("sqr", I.sqr(x).lo, I.sqr(x).hi, *ends(ref_sq), sq)
    compare("sqrt", I.sqrt(x).lo, I.sqrt(x).hi, *ends(ref_rt), rt)


@FEW
@given(SEEDS)
def test_cos_sin_match_codac(seed):
    rng = np.random.default_rng(seed)
    a, b = ivgen.angle_boxes(rng, N)
    x, px = IV.of(a, b), ivgen.points(rng, a, b, 6)
    cx = civs(x)
    # Codac evaluates sin as cos(x - [pi/2]) and reduces huge arguments loosely: its
    # bounds may lie a few ulp of |x| outside the true range (tolerance of check (2)).
    slack = TM + 8 * np.spacing(np.minimum(x.mag(), 1e300))
    for name, ours, fn, feas in (
        ("cos", I.cos(x), codac.cos, np.cos(px)),
        ("sin", I.sin(x), codac.sin, np.sin(px)),
    ):
        with CODAC():
            ref_lo, ref_hi = ends([fn(c) for c in cx])
        compare(name, ours.lo, ours.hi, ref_lo, ref_hi, feas, abs_tol=TMR, contain_tol=slack)


def _circle_hull(arcs: list[tuple[float, float]]) -> tuple[float, float]:
    """Smallest arc holding the given arcs (radians, each shorter than a turn): the
    complement of the largest gap between them; [-pi, pi] if there is none."""
    if not arcs:
        return math.inf, -math.inf
    arcs = sorted((lo % TAU, lo % TAU + (hi - lo)) for lo, hi in arcs)
    merged = [list(arcs[0])]
    for lo, hi in arcs[1:]:
        if lo <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    m = len(merged)
    gaps = [merged[(i + 1) % m][0] + (TAU if i == m - 1 else 0.0) - merged[i][1] for i in range(m)]
    i = int(np.argmax(gaps))
    if gaps[i] <= 0.0:
        return -math.pi, math.pi
    if i == m - 1:
        return merged[0][0], merged[m - 1][1]
    return merged[i + 1][0], merged[i][1] + TAU


def _codac_bearing(cy: codac.Interval, cx: codac.Interval) -> tuple[float, float]:
    """Codac's tightest bearing set of a box (its atan2 is [-pi, pi] across the negative
    x-axis): codac.atan2 on the closed upper pieces x >= 0 and x <= 0, and mirrored on the
    lower ones (bearing(x, -y) = -bearing(x, y)), glued on the circle."""
    if cx.is_empty() or cy.is_empty():
        return math.inf, -math.inf
    pos, neg = codac.Interval(0, codac.oo), codac.Interval(-codac.oo, 0)
    arcs = []
    for sign, qy in ((1.0, cy & pos), (-1.0, -(cy & neg))):
        for qx in (cx & pos, cx & neg):
            if qy.is_empty() or qx.is_empty():
                continue
            a = codac.atan2(qy, qx)
            if not a.is_empty():
                arcs.append((a.lb(), a.ub()) if sign > 0 else (-a.ub(), -a.lb()))
    return _circle_hull(arcs)


@FEW
@given(SEEDS)
def test_bearing_and_atan2_match_codac_modulo_two_pi(seed):
    rng = np.random.default_rng(seed)
    (y, py), (x, px) = _pair(rng), _pair(rng)
    ours = I.bearing(y, x)
    with CODAC():
        ref = np.array([_codac_bearing(b, a) for b, a in zip(civs(y), civs(x), strict=True)]).T
    ref_lo, ref_hi, _ = align_to(ref[0], ref[1], ours.lo, ours.hi)
    # feasible bearings (the origin has none), each on the branch next to our interval
    px, py = ivgen.grid(px, py)
    ang = np.where((px == 0) & (py == 0), np.nan, np.arctan2(py, px))
    k = np.round((ours.mid() - ang) / (2 * math.pi))
    # Deliberately wider: the box {origin}, where Codac's atan2 is empty, is the whole
    # circle for us (the polar relation holds there for every angle).
    origin = (x.lo == 0) & (x.hi == 0) & (y.lo == 0) & (y.hi == 0)
    compare(
        "bearing",
        ours.lo,
        ours.hi,
        ref_lo,
        ref_hi,
        ang + 2 * math.pi * k,
        ulps=8,
        abs_tol=TMR,
        wider_ok=origin,
    )
    # atan2 = bearing plus libm's atan2(0, 0) = 0 where the origin is in the box.
    a = I.atan2(y, x)
    lib = np.arctan2(py, px)
    k = np.round((a.mid() - lib) / (2 * math.pi))
    assert np.all(a.contains(lib + 2 * math.pi * k))
    assert np.all(ours.subset_of(a))


def test_atan2_regression_box_touching_the_origin():
    # Hypothesis found it: [-1.571, 3.927] missed -2.034 + 2*pi (the arc is [pi/2, 3pi/2]).
    y, x = IV.of(-2.06e-192, 1.0), IV.of(-2.06e-192, -2.2e-313)
    a = I.atan2(y, x)
    for p in (-2.034 + 2 * math.pi, math.pi / 2, 3 * math.pi / 2 - 1e-12, math.pi):
        assert bool(a.contains(p))
    assert float(a.width()) < math.pi + 1e-9


def _bwd_case(rng, f, angles=False):
    """(x box, z box, feasible x points): z holds f of a point of x, plus random points
    of x kept where f(point) is in z."""
    a, b = ivgen.angle_boxes(rng, N) if angles else ivgen.boxes(rng, N)
    p = ivgen.points(rng, a, b, 6)
    with np.errstate(all="ignore"):
        fp = f(p)
        fz = np.where(np.isfinite(fp[2]), fp[2], 0.0)
        w = 10.0 ** rng.uniform(-12, 0.5, N)
        zl, zh = fz - w * rng.random(N), fz + w * rng.random(N)
        feas = np.where((fp >= zl) & (fp <= zh), p, np.nan)
    return IV.of(a, b), IV.of(zl, zh), feas


@FEW
@given(SEEDS)
def test_backward_projections_match_codac(seed):
    rng = np.random.default_rng(seed)
    for name, f, ours_fn, op, angles in (
        ("bwd_sqr", np.square, I.bwd_sqr, codac.SqrOp, False),
        ("bwd_cos", np.cos, I.bwd_cos, codac.CosOp, True),
        ("bwd_sin", np.sin, I.bwd_sin, codac.SinOp, True),
    ):
        x, z, feas = _bwd_case(rng, f, angles)
        ours = ours_fn(z, x)
        ref = civs(x)
        with CODAC():
            for zz, xx in zip(civs(z), ref, strict=True):
                op.bwd(zz, xx)
        # Codac gives up on huge angles (|x| > ~1e15: no contraction), which we do not.
        looser = x.mag() > 2.0**48 if angles else None
        # rounding: TRANS_MARGIN (acos/asin) and a few ulp of the branch shift 2*pi*k
        fin = np.minimum(np.where(np.isfinite(x.mag()), x.mag(), 0.0), 1e300)
        tol = TMR + 8 * np.spacing(np.maximum(fin, TAU)) if angles else 0.0
        compare(name, ours.lo, ours.hi, *ends(ref), feas, ulps=8, abs_tol=tol, looser=looser)


@FEW
@given(SEEDS)
def test_backward_mul_matches_codac(seed):
    rng = np.random.default_rng(seed)
    (x, px), (y, py) = _pair(rng), _pair(rng)
    with np.errstate(all="ignore"):
        prod = px * py
        pz = np.where(np.isfinite(prod[2]), prod[2], 0.0)
        w = 10.0 ** rng.uniform(-12, 1, N)
        z = IV.of(pz - w * rng.random(N), pz + w * rng.random(N))
        feas = np.where(z.contains(prod) & np.isfinite(prod), px, np.nan)
    ours = I.bwd_mul(z, x, y)
    ref_x = civs(x)
    with CODAC():
        for zz, xx, yy in zip(civs(z), ref_x, civs(y), strict=True):
            codac.MulOp.bwd(zz, xx, yy)
    compare("bwd_mul", ours.lo, ours.hi, *ends(ref_x), feas, ulps=8)


def _codac_meet(box: codac.Interval, z: codac.Interval) -> codac.Interval:
    """Codac's own 'x = y mod 2*pi' backward step (its CtcPolar's bwd_imod2): box met
    with z + 2*pi*integer((box - z) / 2*pi)."""
    two_pi = 2 * codac.Interval.pi()
    k = codac.integer((box - z) / two_pi)
    return box & (z + k * two_pi)


def _meet_case(rng):
    """(box, z, feasible points): z of any width on any branch; feasible points are
    inner points of z shifted by 2*pi*k into the box (kept below 1e6 in magnitude, where
    the float shift is far more accurate than their distance to the ends of z)."""
    a, b = ivgen.angle_boxes(rng, N)
    p = ivgen.points(rng, a, b, 2)[1 - (rng.random(N) < 0.5), np.arange(N)]
    w = np.where(rng.random(N) < 0.8, 10.0 ** rng.uniform(-6, 0.5, N), rng.uniform(0, 8, N))
    zc = rng.uniform(-math.pi, math.pi, N) + rng.integers(-3, 4, N) * 2 * math.pi
    zl, zh = zc - w * rng.random(N), zc + w * rng.random(N)
    inner = zl + (zh - zl) * rng.uniform(0.1, 0.9, (6, N))
    with np.errstate(all="ignore"):
        k = np.round((p - inner) / (2 * math.pi))
        t = inner + 2 * math.pi * k
    ok = np.isfinite(t) & (np.abs(t) < 1e6) & (t >= a) & (t <= b)
    return IV.of(a, b), IV.of(zl, zh), np.where(ok, t, np.nan)


@FEW
@given(SEEDS)
def test_meet_angle_matches_codac(seed):
    rng = np.random.default_rng(seed)
    box, z, feas = _meet_case(rng)
    ours = I.meet_angle(box, z)
    with CODAC():
        ref = ends([_codac_meet(bb, zz) for bb, zz in zip(civs(box), civs(z), strict=True)])
    # Codac's integer() of a huge quotient cannot resolve branches (no contraction).
    looser = np.maximum(box.mag(), z.mag()) > 2.0**40
    # rounding: a few ulp of the magnitudes in play (the branch shift 2*pi*k and z)
    fin = np.where(np.isfinite(box.mag()), box.mag(), 0.0)
    tol = 8 * np.spacing(np.maximum(np.minimum(np.maximum(fin, z.mag()), 1e300), TAU))
    # The same rounding decides whether a branch reaches the box: where Codac (one
    # directed rounding per operation) finds it short by less than the tolerance, ours
    # (round to nearest, one ulp out) may keep it: a sliver, or, beyond 2^40 rad where a
    # few ulp are a noticeable angle (1 rad at 6e14), the end of that branch.
    sliver = ~(ref[0] <= ref[1]) & (ours.width() <= tol) | looser
    compare(
        "meet_angle",
        ours.lo,
        ours.hi,
        *ref,
        feas,
        ulps=8,
        abs_tol=tol,
        looser=looser,
        wider_ok=sliver,
    )


@FEW
@given(SEEDS)
def test_sinc_half_matches_codac_where_monotone(seed):
    rng = np.random.default_rng(seed)
    a, b = ivgen.angle_boxes(rng, N)
    d, p = IV.of(a, b), ivgen.points(rng, a, b, 6)
    with np.errstate(all="ignore"):
        true = np.where(p == 0, 1.0, np.sin(p / 2) / np.where(p == 0, 1.0, p / 2))
    ours = I.sinc_half(d)
    # sinc decreases in |u| up to its first minimum at 4.4934: the exact range is
    # [sinc(max|u|), sinc(min|u|)], each end evaluated by Codac at the point.
    mono = d.mag() / 2 <= 4.49

    def csinc(u: float) -> codac.Interval:
        if u < 2.0**-20:  # 1 - u^2/6 <= sinc(u) <= 1 (Codac's sin is loose on tiny u)
            return codac.Interval(1.0) - codac.sqr(civ(u, u)) / 6.0 | codac.Interval(1.0)
        return codac.sin(civ(u, u)) / civ(u, u)

    with CODAC():
        ends_m = [csinc(float(m) / 2) for m in d.mag()]
        ends_g = [csinc(float(g) / 2) for g in d.mig()]
        ref = [
            em | eg if ok else codac.Interval(-1, 1)
            for em, eg, ok in zip(ends_m, ends_g, mono, strict=True)
        ]
    ref_lo, ref_hi = ends(ref)
    # Codac's enclosure of sin(u)/u at a point is itself a few ulp of sin(u)/u wide:
    # check (2) up to that width.
    own = np.array([max(em.diam(), eg.diam()) for em, eg in zip(ends_m, ends_g, strict=True)])
    # Beyond the first minimum ours is a guaranteed enclosure, deliberately not the
    # tightest ([-0.2173, 0.1284] or +-1/|u|); Codac's stand-in there is [-1, 1].
    compare(
        "sinc_half",
        ours.lo,
        ours.hi,
        ref_lo,
        ref_hi,
        true,
        ulps=8,
        abs_tol=TMR,
        contain_tol=np.where(mono, own, 0.0),
        looser=~mono,
    )
    assert np.all(ours.lo[~mono] >= -0.2173) and np.all(ours.hi <= 1.0)


def test_sinc_half_regression_turns_beyond_two_pi():
    # sin(d/2)/(d/2) is negative for 2pi < |d| < 4pi: the old bound was clipped at 0.
    for d in (7.0, 8.0, -9.0, 12.0, 30.0):
        true = math.sin(d / 2) / (d / 2)
        assert bool(I.sinc_half(IV.of(d)).contains(true))
        assert bool(I.sinc_half(IV.of(-abs(d), abs(d))).contains(true))
    assert float(I.sinc_half(IV.of(-1e9, 1e9)).lo) <= -0.21723362821122166


def test_meet_angle_regression_headings_wider_than_four_pi():
    # The old branch hull kept k = -2..2 around the centre: 0.1 + 8pi was cut from
    # [-30, 30]; now every branch of any box counts, half-lines included.
    z = IV.around(0.1, 0.01)
    for truth, box in (
        (0.1 + 8 * math.pi, IV.of(-30.0, 30.0)),
        (0.1 - 8 * math.pi, IV.of(-30.0, 30.0)),
    ):
        assert bool(I.meet_angle(box, z).contains(truth))
    big = I.meet_angle(IV.of(-1e4, 1e4), z)
    assert float(big.lo) > -1e4 and float(big.hi) < 1e4  # ends moved onto branches
    assert bool(big.contains(0.1 - 2 * math.pi * 1591))
    half = I.meet_angle(IV.of(0.3, math.inf), z)  # the next branch, 0.09 + 2pi
    assert 0.09 + 2 * math.pi - 1e-12 < float(half.lo) <= 0.09 + 2 * math.pi
    assert float(half.hi) == math.inf


def test_bwd_cos_regression_every_branch():
    # The old bwd_cos left x unchanged unless x lay on one monotone branch of cos.
    out = I.bwd_cos(IV.of(0.9, 1.0), IV.of(0.5, 6.0))
    assert abs(float(out.lo) - (2 * math.pi - math.acos(0.9))) < 1e-12 and float(out.hi) == 6.0
    out = I.bwd_cos(IV.of(0.9, 1.0), IV.of(-100.0, 100.0))
    assert float(out.hi) < 100.0 and float(out.lo) > -100.0
    for k in range(-15, 16):
        assert bool(out.contains(2 * math.pi * k)) or abs(2 * math.pi * k) > 95
