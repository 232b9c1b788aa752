"""The contraction of the sliding window of poses (ekf-vs-cp.txt eq. (5) over the
odometry model eq. (1)-(2)) on floats, incrementally: the daemon's case, a window of
tens of states solved once per step, one new state and a few observations each time.

The constraints are those of ``localization.cp_solve``: the heading chain
``theta[k] = theta[k-1] + dtheta[k]`` through every hard heading box; each step's
displacement (eq. (2) forward) from the contracted headings; the x and y chains
``x[k] = x[k-1] + dx[k]`` through the hard boxes and the GPS boxes, q-relaxed (the
(q+1)-th largest lower and smallest upper bound of the fixes carried to each state,
q = ``gps_outliers``; with q = 0 the fixes are plain hard boxes, and with no more fixes
than q they constrain nothing).

Here each chain is contracted by forward-backward (HC4) sweeps over its links, every
sum rounded outward by one ``nextafter``. The result is the greatest common fixpoint of
the link contractors below the boxes (one forward and one backward sweep reach it), so
it depends neither on the order of evaluation nor on where the window starts. Hence
the previous window's solution can be reused: after a slide the old solution of the
states kept is the fixpoint of the window's constraints without the new ones (the
dropped state's knowledge is in the next state's hard box, ``cp_window``); new states,
tightened boxes and tightened links are propagated from where they changed and the
sweeps stop where a box no longer changes. Anything that loosens a constraint (a fix
leaving a q-relaxed window, a link widened) re-solves from the boxes. Both give the
same bits (``tests/test_cp_incremental.py``). What each solve costs is then the
changes, not the window: most steps contract two or three states.

Against the array solve (``cp_solve.solve_window``), the reference: the array solve
sums increments in prefix sums and widens every bound by a guard of 4 (n + 4) eps
(2 sum|d| + |bound|) for the sums' rounding (``localization.chain``); a path of at most
n - 1 links rounded outward at each link errs by less than 1.5 (n - 1) eps
(|bound| + 2 sum|d|), under half of that guard, so every bound here is at least as
tight as the array solve's on the same boxes (up to libm's last bit in the
displacements, as for the rest of the scalar path), and as sound. Where a box comes out
empty (the error bounds were broken: the array solve then raises q, a relaxation) or
the headings are unbounded, or ``hc4_odometry`` is on, ``interval_scalar.Fallback`` is
raised and the caller runs the array solve on the same window.
"""

from __future__ import annotations

import math

from localization import cp_scalar as cps
from localization import interval_scalar as isc
from localization.cp_config import CPConfig
from localization.cp_solve import SolutionF

_INF = math.inf
_nx = math.nextafter
_fin = math.isfinite

Lists = tuple[list[float], list[float]]


class StepTerms:
    """One step's wheel terms (eq. (1): dS = (dSr + dSl)/2, dtheta = (dSr - dSl)/e) and
    its last displacement (dx, dy of eq. (2)) with the headings it came from."""

    __slots__ = ("ds", "dth", "key", "dx", "dy")

    def __init__(self, dsr: isc.Iv, dsl: isc.Iv, e: isc.Iv) -> None:
        self.ds = isc.mul(isc.add(dsr, dsl), (0.5, 0.5))
        self.dth = isc.div(isc.sub(dsr, dsl), e)
        self.key: tuple[float, float, float, float] | None = None
        self.dx: isc.Iv = isc.EMPTY
        self.dy: isc.Iv = isc.EMPTY

    def displacement(self, t0: isc.Iv, t1: isc.Iv, c: CPConfig) -> tuple[isc.Iv, isc.Iv]:
        """(dx, dy) from the headings ``t0``, ``t1`` (finite), kept while they stay."""
        key = (t0[0], t0[1], t1[0], t1[1])
        if key != self.key:
            self.dx, self.dy = cps.displacement(t0, t1, self.ds, self.dth, c.kappa, c.chord)
            self.key = key
        return self.dx, self.dy


def sweep(lo: list[float], hi: list[float], dl: list[float], dh: list[float], s0: int, s1: int):
    """Contract ``v`` (bounds ``lo``, ``hi``, in place) by the links
    ``v[k] = v[k-1] + d[k]`` (k >= 1; ``d[0]`` unused) to their greatest fixpoint, given
    that every link holds already except around the states ``s0`` .. ``s1`` (boxes
    tightened, links tightened, or new states): one forward sweep from ``s0`` and one
    backward sweep, each carried on while boxes change. Returns the first and last
    state changed (-1, -1 for none); :class:`Fallback` on an empty box."""
    n = len(lo)
    c0, c1 = n, -1
    last = s1
    for k in range(max(s0, 1), n):
        a = _nx(lo[k - 1] + dl[k], -_INF)
        b = _nx(hi[k - 1] + dh[k], _INF)
        ch = False
        if a > lo[k]:
            lo[k], ch = a, True
        if b < hi[k]:
            hi[k], ch = b, True
        if ch:
            if not lo[k] <= hi[k]:
                raise isc.Fallback
            c0 = min(c0, k)
            c1 = last = k
        elif k > s1:
            break
    for k in range(max(last, s1), 0, -1):
        a = _nx(lo[k] - dh[k], -_INF)
        b = _nx(hi[k] - dl[k], _INF)
        ch = False
        if a > lo[k - 1]:
            lo[k - 1], ch = a, True
        if b < hi[k - 1]:
            hi[k - 1], ch = b, True
        if ch:
            if not lo[k - 1] <= hi[k - 1]:
                raise isc.Fallback
            c0 = min(c0, k - 1)
            c1 = max(c1, k - 1)
        elif k - 1 < s0:
            break
    return (c0, c1) if c1 >= 0 else (-1, -1)


def _row(j: int, g: isc.Iv, dl: list[float], dh: list[float], n: int) -> Lists:
    """A fix (box ``g`` of state j) carried along the chain to every state, rounded
    outward at each link."""
    lo, hi = [0.0] * n, [0.0] * n
    lo[j], hi[j] = g
    for k in range(j + 1, n):
        lo[k] = _nx(lo[k - 1] + dl[k], -_INF)
        hi[k] = _nx(hi[k - 1] + dh[k], _INF)
    for k in range(j, 0, -1):
        lo[k - 1] = _nx(lo[k] - dh[k], -_INF)
        hi[k - 1] = _nx(hi[k] - dl[k], _INF)
    return lo, hi


class _Axis:
    """x or y: its links (dx or dy of every step; index 0 unused), the boxes B (hard box
    met with what the fixes allow), the fixes' rows and relaxed bounds (q-relaxed mode),
    and the solution."""

    def __init__(self, i: int) -> None:
        self.i = i  # X or Y
        self.dl: list[float] = [0.0]
        self.dh: list[float] = [0.0]
        self.bl: list[float] = []
        self.bh: list[float] = []
        self.rows: list[tuple[int, list[float], list[float]]] = []  # (stamp, lo, hi)
        self.rl: list[float] = []
        self.rh: list[float] = []
        self.sl: list[float] = []
        self.sh: list[float] = []

    def drop(self, k: int) -> None:
        for v in (self.dl, self.dh, self.bl, self.bh, self.rl, self.rh, self.sl, self.sh):
            del v[:k]
        if k and self.dl:
            self.dl[0] = self.dh[0] = 0.0
        for _, lo, hi in self.rows:
            del lo[:k], hi[:k]

    def relaxed(self, q: int, start: int) -> None:
        """The (q+1)-th largest lower and smallest upper bound over the rows, of the
        states from ``start`` on."""
        rows, r = self.rows, len(self.rows) - 1 - q
        del self.rl[start:], self.rh[start:]
        self.rl.extend(sorted(c)[r] for c in zip(*[lo[start:] for _, lo, _ in rows], strict=True))
        self.rh.extend(sorted(c)[q] for c in zip(*[hi[start:] for _, _, hi in rows], strict=True))

    def box(self, k: int, w, mode: str) -> isc.Iv:
        """B of state k: the hard box met with its fix (q = 0) or the relaxed bounds."""
        lo, hi = w.lo[self.i][k], w.hi[self.i][k]
        if mode == "rows":
            a, b = self.rl[k], self.rh[k]
        elif mode == "hard" and w.gps[k] is not None:
            j = 2 * self.i - 2
            a, b = w.gps[k][j], w.gps[k][j + 1]
        else:
            return lo, hi
        return (a if a > lo else lo), (b if b < hi else hi)

    def positions(self, w, mode: str, kept: int, fresh: bool, redo: list[int], l0: int):
        """The chain through the boxes: from the boxes when ``fresh`` or a box widened,
        else from the kept solution met with the new boxes of the states ``redo`` and of
        the new states, swept from what changed (those, and the links from ``l0``)."""
        n = len(w.stamps)
        lo, hi = self.sl, self.sh
        s0 = n if l0 < 0 else l0
        if not fresh:
            for k in redo:
                a, b = self.box(k, w, mode)
                if a < self.bl[k] or b > self.bh[k]:
                    fresh = True
                    break
                self.bl[k], self.bh[k] = a, b
                if a > lo[k] or b < hi[k]:
                    lo[k], hi[k] = max(lo[k], a), min(hi[k], b)
                    if not lo[k] <= hi[k]:
                        raise isc.Fallback
                    s0 = min(s0, k)
        if fresh:
            kept, s0 = 0, 0
            del self.bl[:], self.bh[:], lo[:], hi[:]
        for k in range(kept, n):
            a, b = self.box(k, w, mode)
            if not a <= b:
                raise isc.Fallback
            self.bl.append(a)
            self.bh.append(b)
        lo.extend(self.bl[kept:])
        hi.extend(self.bh[kept:])
        s0 = min(s0, kept)
        if s0 < n:
            sweep(lo, hi, self.dl, self.dh, s0, n - 1)


class IncrementalSolver:
    """The window's contraction, kept between solves (module doc)."""

    def __init__(self, cfg: CPConfig) -> None:
        self.cfg = cfg
        self.solves = 0  # solves, and of them ...
        self.fresh = 0  # ... with the positions solved from the boxes
        self.pause = 0  # solves left to the array solve after a fallback
        self.reset()

    def reset(self) -> None:
        """Forget the previous solution: the next solve starts from the boxes."""
        self.stamps: list[int] = []
        self.hard: list[list[float]] = [[] for _ in range(6)]  # lo[TH, X, Y], hi[TH, X, Y]
        self.gps: list[tuple[float, float, float, float, int] | None] = []
        self.tl: list[float] = []
        self.th: list[float] = []
        self.dl: list[float] = [0.0]  # dtheta of every step (index 0 unused)
        self.dh: list[float] = [0.0]
        self.ax, self.ay = _Axis(1), _Axis(2)
        self.mode = ""

    def solve(self, w, e: isc.Iv) -> SolutionF:
        """Contract the window ``w`` (``cp_solve.SlidingWindow``; ``e`` the wheelbase
        interval). :class:`Fallback` outside the common case; the kept solution is then
        forgotten, and the next ``window + 1`` solves fall back too."""
        if self.pause:
            self.pause -= 1
            raise isc.Fallback
        try:
            return self._solve(w, e)
        except isc.Fallback:
            # What did not apply (an empty box: the bounds were broken; unbounded
            # headings) stays in the window until it has turned over: the array solve
            # till then, rather than a failed try before it at every step.
            self.reset()
            self.pause = max(self.cfg.window, 1) + 1
            raise

    def _align(self, w) -> tuple[int, int, list[list[int]]]:
        """States dropped and kept since the last solve, and the kept states whose hard
        box changed (per axis TH, X, Y); (all, 0, ...) when the solution cannot be
        reused (another window, a hard box widened)."""
        old, new = self.stamps, w.stamps
        changed: list[list[int]] = [[], [], []]
        if not old:
            return 0, 0, changed
        try:
            off = old.index(new[0])
        except ValueError:
            return len(old), 0, changed
        kept = len(old) - off
        if kept > len(new) or old[off:] != new[:kept]:
            return len(old), 0, changed
        for i, (now, was) in enumerate(zip((*w.lo, *w.hi), self.hard, strict=True)):
            if now[:kept] != was[off:]:
                # (state 0 holds the prior merged at the slide; the others rarely change)
                for k in [0] if now[1:kept] == was[off + 1 :] else range(kept):
                    a, b = now[k], was[off + k]
                    if a != b:
                        if (a < b) if i < 3 else (a > b):
                            return len(old), 0, [[], [], []]  # (hard boxes only tighten)
                        changed[i % 3].append(k)
        return off, kept, changed

    def _solve(self, w, e: isc.Iv) -> SolutionF:
        c = self.cfg
        if c.hc4_odometry:
            raise isc.Fallback
        n = len(w.stamps)
        off, kept, changed = self._align(w)
        if kept == 0:
            self.reset()
        self.solves += 1
        for i in range(3):
            lo, hi = w.lo[i], w.hi[i]
            for k in range(kept, n):
                if not lo[k] <= hi[k] or lo[k] == _INF or hi[k] == -_INF:
                    raise isc.Fallback
        terms = w.terms
        if None in terms[1:]:
            for k in range(1, n):
                if terms[k] is None:
                    terms[k] = StepTerms(w.dsr[k], w.dsl[k], e)
        # 1. headings: the kept solution met with the changed hard boxes, new states.
        tl, th, dl, dh = self.tl, self.th, self.dl, self.dh
        for v in (tl, th, dl, dh):
            del v[:off]
        if kept:
            dl[0] = dh[0] = 0.0
        for k in range(max(kept, 1), n):
            a, b = terms[k].dth
            if not (a <= b and _fin(a) and _fin(b)):
                raise isc.Fallback
            dl.append(a)
            dh.append(b)
        s0 = kept
        hl, hh = w.lo[0], w.hi[0]
        for k in changed[0]:
            if hl[k] > tl[k] or hh[k] < th[k]:
                tl[k], th[k] = max(tl[k], hl[k]), min(th[k], hh[k])
                if not tl[k] <= th[k]:
                    raise isc.Fallback
                s0 = min(s0, k)
        tl.extend(hl[kept:])
        th.extend(hh[kept:])
        c0, c1 = sweep(tl, th, dl, dh, s0, n - 1) if s0 < n else (-1, -1)
        # 2. displacements of the steps next to a changed heading, and of the new steps.
        ax, ay = self.ax, self.ay
        ax.drop(off)
        ay.drop(off)
        first = kept if c1 < 0 else min(kept, max(c0, 1))
        last = n - 1 if kept < n else (min(c1 + 1, n - 1) if c1 >= 0 else 0)
        loose, l0 = False, -1  # a link widened; the first link changed
        for k in range(max(first, 1), last + 1):
            t0, t1 = (tl[k - 1], th[k - 1]), (tl[k], th[k])
            if not (_fin(t0[0]) and _fin(t0[1]) and _fin(t1[0]) and _fin(t1[1])):
                raise isc.Fallback
            dx, dy = terms[k].displacement(t0, t1, c)
            if k < kept:
                old = (ax.dl[k], ax.dh[k], ay.dl[k], ay.dh[k])
                if old == (dx[0], dx[1], dy[0], dy[1]):
                    continue
                loose = (
                    loose or dx[0] < old[0] or dx[1] > old[1] or dy[0] < old[2] or dy[1] > old[3]
                )
                ax.dl[k], ax.dh[k], ay.dl[k], ay.dh[k] = dx[0], dx[1], dy[0], dy[1]
                l0 = k - 1 if l0 < 0 else l0
            else:
                ax.dl.append(dx[0])
                ax.dh.append(dx[1])
                ay.dl.append(dy[0])
                ay.dh.append(dy[1])
        # 3. x and y.
        at = [k for k, g in enumerate(w.gps) if g is not None]
        q = c.gps_outliers
        mode = "hard" if q == 0 else ("none" if len(at) <= q else "rows")
        added = [k for k in at if k >= kept]  # fixes of new states, or new fixes:
        refix = False  # a fix of a kept state changed
        if kept and w.gps[:kept] != self.gps[off:]:
            for k in range(kept):
                g0, g1 = self.gps[off + k], w.gps[k]
                if g0 != g1:
                    refix = refix or g0 is not None
                    added.append(k)
        fresh = loose or refix or mode != self.mode or kept == 0
        bad: list[int] = []
        rx_from = kept  # the relaxed bounds changed from this state on
        if mode == "rows":
            lost, rx_from = self._rows(w, at, kept, added, q, refix, l0)
            fresh = fresh or lost
            for k in at:
                g = w.gps[k]
                if not (
                    g[0] <= ax.rh[k] and g[1] >= ax.rl[k] and g[2] <= ay.rh[k] and g[3] >= ay.rl[k]
                ):
                    bad.append(k)
        self.mode = mode
        if fresh:
            self.fresh += 1
        for axis in (ax, ay):
            redo = set(changed[axis.i]) | {k for k in added if k < kept}
            axis.positions(w, mode, kept, fresh, sorted(redo.union(range(rx_from, kept))), l0)
        self.stamps = list(w.stamps)
        self.hard = [list(v) for v in (*w.lo, *w.hi)]
        self.gps = list(w.gps)
        return SolutionF(ax.sl[:], ax.sh[:], ay.sl[:], ay.sh[:], tl[:], th[:], False, bad)

    def _rows(
        self, w, at: list[int], kept: int, added: list[int], q: int, rebuild: bool, l0: int
    ) -> tuple[bool, int]:
        """The fixes' rows and relaxed bounds of both axes: rebuilt when ``rebuild``
        (another mode before, a fix changed), else the rows of the fixes still in the
        window carried on (redone beyond the first changed link ``l0``, and to the new
        states), with rows for the ``added`` fixes. Returns whether a fix left the
        window (the relaxed bounds may widen: the positions start from the boxes) and
        the first state whose relaxed bounds changed."""
        n, first = len(w.stamps), w.stamps[0]
        rebuild = rebuild or self.mode != "rows"
        lost = False
        for axis in (self.ax, self.ay):
            rows = [r for r in axis.rows if r[0] >= first]
            lost = lost or len(rows) != len(axis.rows)
            axis.rows = rows
        state = {st: k for k, st in enumerate(w.stamps)}
        start = kept
        for axis in (self.ax, self.ay):
            j = 2 * axis.i - 2
            dl, dh = axis.dl, axis.dh
            if rebuild:
                axis.rows = [
                    (w.stamps[k], *_row(k, (w.gps[k][j], w.gps[k][j + 1]), dl, dh, n)) for k in at
                ]
                start = 0
            else:
                rows = []
                for st, lo, hi in axis.rows:
                    k0 = state[st]
                    if 0 <= l0 < k0:  # a link before the fix changed: the row redone
                        g = (w.gps[k0][j], w.gps[k0][j + 1])
                        rows.append((st, *_row(k0, g, dl, dh, n)))
                        start = 0
                        continue
                    # carried on beyond the first changed link, and to the new states
                    k1 = l0 + 1 if l0 >= 0 else len(lo)
                    del lo[k1:], hi[k1:]
                    for k in range(k1, n):
                        lo.append(_nx(lo[k - 1] + dl[k], -_INF))
                        hi.append(_nx(hi[k - 1] + dh[k], _INF))
                    rows.append((st, lo, hi))
                    start = min(start, k1)
                for k in added:
                    g = (w.gps[k][j], w.gps[k][j + 1])
                    rows.append((w.stamps[k], *_row(k, g, dl, dh, n)))
                rows.sort(key=lambda r: r[0])
                axis.rows = rows
                if lost or added:  # another set of fixes: every state's order statistics
                    start = 0
        for axis in (self.ax, self.ay):
            axis.relaxed(q, start)
        return lost, start
