"""The incremental window contraction on floats (localization.cp_incremental): the
sweeps reach the greatest fixpoint; solving incrementally gives the same bits as
solving from the boxes; the boxes are sound (sampled feasible trajectories of random
windows, the simulator's truth) and never wider than the array solve's
(localization.cp_solve, the reference); the service's box-free feeds; relative() with
no peer."""

from __future__ import annotations

import math

import numpy as np
import pytest

import localization.interval_scalar as isc
from fakes.world.paper_scenario import simulate
from localization.cp import CPConfig, CPLocalizer
from localization.cp_incremental import IncrementalSolver, StepTerms, sweep
from localization.cp_solve import SlidingWindow, solve_window
from localization.cp_window import SlidingWindowCP
from localization.interval import IV
from msgs import GpsFix, GyroSample, Pose2D, RobotOdometry

_nx = math.nextafter


def _fixpoint(lo, hi, dl, dh):
    """The link contractors applied until nothing changes (any order reaches it)."""
    lo, hi = list(lo), list(hi)
    while True:
        old = (list(lo), list(hi))
        for k in range(1, len(lo)):
            lo[k] = max(lo[k], _nx(lo[k - 1] + dl[k], -math.inf))
            hi[k] = min(hi[k], _nx(hi[k - 1] + dh[k], math.inf))
        for k in range(len(lo) - 1, 0, -1):
            lo[k - 1] = max(lo[k - 1], _nx(lo[k] - dh[k], -math.inf))
            hi[k - 1] = min(hi[k - 1], _nx(hi[k] - dl[k], math.inf))
        if (lo, hi) == old:
            return lo, hi


@pytest.mark.parametrize("seed", range(40))
def test_sweep_reaches_the_fixpoint_from_the_boxes_and_from_a_changed_fixpoint(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 30))
    truth = np.cumsum(rng.normal(0, 1, n))
    d = np.diff(truth, prepend=0.0)
    dl = list(d - rng.uniform(0, 0.2, n))
    dh = list(d + rng.uniform(0, 0.2, n))
    lo = [t - rng.uniform(0, 3) if rng.random() < 0.4 else -math.inf for t in truth]
    hi = [t + rng.uniform(0, 3) if rng.random() < 0.4 else math.inf for t in truth]
    ref = _fixpoint(lo, hi, dl, dh)
    a, b = list(lo), list(hi)
    sweep(a, b, dl, dh, 0, n - 1)
    assert (a, b) == ref
    # tighten some boxes of the fixpoint; sweep only from what changed
    k0, k1 = sorted(int(k) for k in rng.integers(0, n, 2))
    lo2, hi2 = list(lo), list(hi)
    for k in range(k0, k1 + 1):
        lo2[k] = max(lo2[k], truth[k] - rng.uniform(0, 1))
        hi2[k] = min(hi2[k], truth[k] + rng.uniform(0, 1))
        a[k], b[k] = max(a[k], lo2[k]), min(b[k], hi2[k])
    sweep(a, b, dl, dh, k0, k1)
    assert (a, b) == _fixpoint(lo2, hi2, dl, dh)
    assert all(x <= t <= y for x, t, y in zip(a, truth, b, strict=True))


def _arc(p, dsr, dsl, e):
    """The exact motion of eq. (1)-(2) (kappa = 1/2, chord factor)."""
    x, y, th = p
    ds, dth = 0.5 * (dsr + dsl), (dsr - dsl) / e
    c = 1.0 if dth == 0.0 else math.sin(dth / 2) / (dth / 2)
    return x + ds * c * math.cos(th + dth / 2), y + ds * c * math.sin(th + dth / 2), th + dth


def _random_window(rng, q: int):
    """A window of random steps around a true path: prior, headings, hard position
    boxes, fixes (at most q of them wrong), and the error bounds."""
    n = int(rng.integers(1, 16))
    cfg = CPConfig(
        wheel_abs_bound_m=0.002,
        wheel_rel_bound=0.02,
        wheelbase_bound_m=0.005,
        gps_outliers=q,
        gps_bound_m=1.0,
    )
    e_true = cfg.wheelbase_m + rng.uniform(-1, 1) * cfg.wheelbase_bound_m
    w = SlidingWindow()
    e = IV.around(cfg.wheelbase_m, cfg.wheelbase_bound_m)
    ef = (float(e.lo), float(e.hi))
    p = (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-3, 3))
    path, wheels = [p], [(0.0, 0.0)]
    for _ in range(1, n):
        tr, tl = rng.uniform(-0.05, 0.3), rng.uniform(-0.05, 0.3)
        p = _arc(p, tr, tl, e_true)
        path.append(p)
        wheels.append((tr, tl))
    for k in range(n):
        if k:
            tr, tl = wheels[k]
            err = rng.uniform(-1, 1, 2) * cfg.wheel_abs_bound_m
            mr, ml = tr + err[0], tl + err[1]
            r = isc.around(mr, cfg.wheel_abs_bound_m + cfg.wheel_rel_bound * abs(mr))
            l = isc.around(ml, cfg.wheel_abs_bound_m + cfg.wheel_rel_bound * abs(ml))
            assert r[0] <= tr <= r[1] and l[0] <= tl <= l[1]
        else:
            r = l = (0.0, 0.0)
        w.append(k, (None, None, None), r, l, StepTerms(r, l, ef) if k else None)
        x, y, th = path[k]
        for i, v, wid in ((0, th, 0.3), (1, x, 1.5), (2, y, 1.5)):
            if k == 0 or rng.random() < (0.6 if i == 0 else 0.15):
                rad = rng.uniform(0.01, wid)
                w.lo[i][k], w.hi[i][k] = v - rad * rng.uniform(0, 1), v + rad * rng.uniform(0, 1)
        if rng.random() < 0.5:
            off = rng.uniform(-1, 1, 2) * cfg.gps_bound_m
            w.gps[k] = (x + off[0] - 1.0, x + off[0] + 1.0, y + off[1] - 1.0, y + off[1] + 1.0, k)
    wrong = [k for k, g in enumerate(w.gps) if g is not None][:q]
    for k in wrong:  # outliers: off by far more than the bound
        g = w.gps[k]
        w.gps[k] = (g[0] + 9.0, g[1] + 9.0, g[2] - 7.0, g[3] - 7.0, k)
    return w, cfg, e, path, wheels, e_true


def _feasible(rng, w, cfg, e, path, wheels, e_true, tries=400):
    """Trajectories of the model with wheel travels, wheelbase and first pose drawn
    inside their intervals, kept where they meet every hard box and all but at most q
    fixes: sampled feasible points of the window's constraints (the truth first)."""
    n, out = len(path), [np.array(path)]
    for _ in range(tries):
        p0 = tuple(rng.uniform(w.lo[i][0], w.hi[i][0]) for i in (1, 2, 0))
        ee = rng.uniform(float(e.lo), float(e.hi))
        ps = [p0]
        for k in range(1, n):
            dsr, dsl = rng.uniform(*w.dsr[k]), rng.uniform(*w.dsl[k])
            ps.append(_arc(ps[-1], dsr, dsl, ee))
        pa = np.array(ps)
        ok = all(
            w.lo[i][k] <= pa[k, j] <= w.hi[i][k]
            for k in range(n)
            for i, j in ((0, 2), (1, 0), (2, 1))
        )
        bad = sum(
            1
            for k, g in enumerate(w.gps)
            if g is not None and not (g[0] <= pa[k, 0] <= g[1] and g[2] <= pa[k, 1] <= g[3])
        )
        if ok and bad <= cfg.gps_outliers:
            out.append(pa)
    return out


@pytest.mark.parametrize("seed", range(60))
def test_window_solve_keeps_feasible_points_and_is_inside_the_array_solve(seed):
    rng = np.random.default_rng(seed)
    w, cfg, e, path, wheels, e_true = _random_window(rng, int(rng.integers(0, 3)))
    try:
        sol = IncrementalSolver(cfg).solve(w, (float(e.lo), float(e.hi)))
    except isc.Fallback:
        return  # the array solve runs: nothing of this path to check
    ref = solve_window(w.arrays(), cfg, e)
    for got, (lo, hi) in zip(
        ((sol.tl, sol.th), (sol.xl, sol.xh), (sol.yl, sol.yh)),
        ((ref.th.lo, ref.th.hi), (ref.x.lo, ref.x.hi), (ref.y.lo, ref.y.hi)),
        strict=True,
    ):
        assert np.all(np.array(got[0]) >= lo) and np.all(np.array(got[1]) <= hi)
    pts = _feasible(rng, w, cfg, e, path, wheels, e_true)
    tol = 1e-9  # the samples' own float rounding
    for pa in pts:
        for (lo, hi), j in (((sol.xl, sol.xh), 0), ((sol.yl, sol.yh), 1), ((sol.tl, sol.th), 2)):
            assert np.all(np.array(lo) - tol <= pa[:, j]) and np.all(pa[:, j] <= np.array(hi) + tol)


class _FromBoxes(CPLocalizer):
    """Every solve from the boxes (no reuse of the previous solution)."""

    def _solve(self):
        if self._dirty or self._sol is None:
            self._inc.reset()
        return super()._solve()


def _cfg(sc, **kw) -> CPConfig:
    b = sc.bounds
    return CPConfig(
        wheelbase_m=sc.wheelbase_m,
        wheel_abs_bound_m=b.wheel_abs_m,
        wheel_rel_bound=b.wheel_rel,
        gps_bound_m=b.gps_m,
        gyro_bound_rad=b.gyro_rad,
        **kw,
    )


def _run(sc, i, cfg, locs, rng, check):
    """Feed robot i's own sensors (a heading most steps, fixes, now and then a hard
    position box around the truth as a peer contraction would give, and a window solve
    mid-step) to every localizer alike; ``check(s)`` after each event."""
    b = sc.bounds
    for cp in locs:
        cp.start(
            0,
            IV.around(sc.gps[i, 0, 0], b.gps_m),
            IV.around(sc.gps[i, 0, 1], b.gps_m),
            IV.around(sc.gyro[i, 0], b.gyro_rad),
        )
    for s in range(sc.steps):
        st = int(sc.stamps_ns[s])
        ev = rng.random(4)
        for cp in locs:
            if s:
                cp.step(st, sc.dsr[i, s], sc.dsl[i, s])
        check(s)
        if ev[0] < 0.9:
            for cp in locs:
                cp.heading(st, IV.around(sc.gyro[i, s], b.gyro_rad))
        if ev[3] < 0.1:
            for cp in locs:
                cp.window_arrays()  # a solve mid-step; more boxes come after it
        if not np.isnan(sc.gps[i, s, 0]):
            for cp in locs:
                cp.gps(st, *sc.gps[i, s])
        if ev[1] < 0.1:
            t, r = sc.truth[i, s], ev[2] * 2.0
            for cp in locs:
                cp.position_box(IV.of(t[0] - r, t[0] + 0.3), IV.of(t[1] - 0.3, t[1] + r))
        check(s)


CASES = [  # seed, window, q, gps_every, gps jumps (robot 0 step, dx, dy)
    (1, 20, 0, 1, ()),
    (2, 1, 0, 3, ()),
    (3, 12, 1, 2, ((0, 20, 12.0, -9.0),)),
    (4, 30, 2, 4, ((0, 15, -14.0, 5.0), (0, 31, 9.0, 9.0))),
    (5, 3, 1, 1, ()),
    (6, 40, 2, 10, ()),
    (7, 8, 0, 1, ((0, 25, 15.0, -12.0),)),  # a jump with q = 0: relaxed, array solve
]


@pytest.mark.parametrize("seed,window,q,gps_every,jumps", CASES)
def test_incremental_solves_equal_solves_from_the_boxes(seed, window, q, gps_every, jumps):
    sc = simulate(duration_s=6.0, seed=seed, gps_every=gps_every, gps_jumps=jumps)
    cfg = _cfg(sc, window=window, gps_outliers=q)
    a, b = CPLocalizer(cfg), _FromBoxes(cfg)

    def check(s):
        assert [tuple(v) for v in a.current()] == [tuple(v) for v in b.current()]
        sa, sb = a._sol, b._sol
        assert (sa is None) == (sb is None)
        if sa is not None:
            assert sa == sb

    _run(sc, 0, cfg, [a, b], np.random.default_rng(seed), check)
    assert a._inc.fresh < a._inc.solves  # the incremental path ran
    # a jump beyond q: relaxed (by the array solve) while it is in the window, then the
    # float solve again
    assert (a.relaxations > 0) == bool(jumps and q == 0) and a._inc.pause == 0


def _boxes(cp):
    return [(float(v.lo), float(v.hi)) for v in cp.current()]


@pytest.mark.parametrize("seed,window,q,gps_every,jumps", CASES)
def test_inside_the_array_path_and_contains_the_truth(seed, window, q, gps_every, jumps):
    sc = simulate(duration_s=6.0, seed=seed, gps_every=gps_every, gps_jumps=jumps)
    cfg = _cfg(sc, window=window, gps_outliers=q)
    for i in range(3):
        a, r = CPLocalizer(cfg), CPLocalizer(cfg)
        r.scalar_path = False
        worst = [0.0]

        def check(s, a=a, r=r, i=i, worst=worst):
            t = sc.truth[i, s]
            for (lo, hi), (rl, rh), v in zip(_boxes(a), _boxes(r), t, strict=True):
                assert rl <= lo and hi <= rh, s
                assert lo <= v <= hi or not (rl <= v <= rh), s  # truth kept as the array path
                worst[0] = max(worst[0], lo - rl, rh - hi)

        _run(sc, i, cfg, [a, r], np.random.default_rng(seed), check)
        assert worst[0] < 1e-6  # tighter by the rounding only
        _, ax, ay, ath = a.window_arrays()
        _, rx, ry, rth = r.window_arrays()
        for u, v in ((ax, rx), (ay, ry), (ath, rth)):
            assert np.all(u.lo >= v.lo) and np.all(u.hi <= v.hi)
        assert a.dropped_gps == r.dropped_gps and a.relaxations == r.relaxations


def test_unbounded_headings_run_the_array_solve():
    """No heading known: the float solve does not apply; the array solve's boxes."""
    out = []
    for scalar in (False, True):
        cp = SlidingWindowCP(CPConfig(window=5))
        cp.scalar_path = scalar
        cp.start(0, IV.of(0.0, 1.0), IV.of(0.0, 1.0))
        for s in range(1, 8):
            cp.step(s * 10**8, 0.1, 0.12)
            cp.gps(s * 10**8, 0.1 * s, 0.0)
        out.append([(float(v.lo), float(v.hi)) for v in cp.current()])
    assert out[0] == out[1]


def test_relative_with_no_peer_changes_nothing():
    for scalar in (False, True):
        cp = SlidingWindowCP()
        cp.scalar_path = scalar
        cp.start(0, IV.of(0.0, 1.0), IV.of(0.0, 1.0), IV.of(0.0, 0.1))
        before = _boxes(cp)
        empty = IV.of(np.zeros(0), np.zeros(0))
        assert cp.relative(0, empty, empty, empty, empty) is True
        assert _boxes(cp) == before and not cp.skipped


def test_take_feeds_then_box_equal_the_feeds():
    """The service's box-free feeds (take_*) and box() give the feeds' boxes."""
    sc = simulate(duration_s=3.0, seed=9)
    cfg = _cfg(sc, window=10)
    a, b = CPLocalizer(cfg, "r"), CPLocalizer(cfg, "r")
    odo = Pose2D(0.0, 0.0, 0.0)
    from localization.odometry import motion

    for s in range(sc.steps):
        st = int(sc.stamps_ns[s])
        if s:
            p = motion(
                np.array([odo.x, odo.y, odo.theta]), (sc.dsr[0, s], sc.dsl[0, s]), cfg.wheelbase_m
            )
            odo = Pose2D(*(float(v) for v in p))
        msgs = [RobotOdometry(st, odo, 0.0, 0.0, 0.0, 0.0, 12.5, True, True)]
        msgs.append(GyroSample(st, 0.0, float(sc.gyro[0, s])))
        if not np.isnan(sc.gps[0, s, 0]):
            msgs.append(
                GpsFix(
                    st,
                    mode=3,
                    quality=1,
                    east_m=float(sc.gps[0, s, 0]),
                    north_m=float(sc.gps[0, s, 1]),
                )
            )
        for m in msgs:
            got = a.feed(m)
            take = {
                RobotOdometry: lambda m: b.take_odometry(m),
                GyroSample: lambda m: b.take_gyro(m.stamp_ns, m.angle_rad),
                GpsFix: lambda m: b.take_gps(m),
            }[type(m)]
            changed = take(m)
            assert (got is None) == (not changed)
            if got is not None:
                assert got == b.box() and b.stamp_ns == got.stamp_ns
