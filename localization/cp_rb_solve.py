"""Contraction of a window of real-robot states with the q-relaxed intersection over
every observation (issue 14 items 2-3; ekf-vs-cp.txt eq. (5) with the relaxed
intersection of Jaulin's set-membership methods).

Unknowns, per state k of the window: position x_k, y_k, heading th_k, and the heading
offset c_k = th_k - Theta_k - s_k of the velocity-odometry model
(``localization.velocity_odometry``: Theta_k the commanded heading, |s_k| <= a/2).
Constraints:

- hard (never relaxed): the window's prior (the state that left the window), the chains
  c_{k+1} - c_k in [-dc_k, dc_k] and x_{k+1} - x_k in dx_k, y likewise, with dx_k, dy_k
  from the headings inside the step;
- relaxable: every observation j (landmark, peer seen, seen by a peer) at its state.

**Relaxed intersection.** Each pass contracts every observation with the current box of
its state (``localization.range_bearing``), projects the results onto every state along
the chains, and keeps at each state what all but at most q of them allow (the (q+1)-th
largest lower and smallest upper bound, ``chain.relaxed_chain_at``), for x, y and c;
the heading of a state also meets the relaxed intersection of its own observations.
If at most q observations of the window are wrong, every correct one contracts a box
that holds the truth into one that still does, so each pass, and the result, holds the
truth: **the truth is inside unless more than q observations of the window broke their
bounds** (or a prior from an earlier window did). An observation whose contraction is
empty, or misses the final box, is named inconsistent; more than q of them leave some
state empty, which the caller reports instead of a box.

**Heading pieces** (``localization.cp_rb_pieces``): the newest camera heading is cut
into pieces (sectors of the circle when it is unknown), solved at once along a batch
axis and joined; the live pieces are kept for the next solve (a sub-paving).

**Unions.** An observation by a peer given as its pieces (the peer is in one of them) is
one column per piece: each is contracted, and the observation's box is the hull of the
columns not proven empty (empty only if all are). It is then one observation for the
relaxation and the naming. Sound: the true observer lies in some piece, whose column
keeps the truth.

**Two heading chains.** The offset chain c carries the pair condition a + dc; where a
step's long-turn bound ``dw`` is smaller (``localization.velocity_odometry``), the
headings are also chained directly, th_{k+1} - th_k in the commanded turn +- dw, and the
headings inside the step bounded from both its ends.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from localization import interval_kernels as K
from localization.chain import chain_k, leave_out, projections, relaxed_chain_at
from localization.cp_rb_pieces import any_empty, heading_pieces, meet_box, widen_box
from localization.interval_trig import TWO_PI
from localization.range_bearing import AX, AY, OTH, OX, OY, contract_observation
from localization.velocity_odometry import GUARD, displacements

_INF = np.inf
#: Above this many hypotheses (m choose q) the relaxation is done axis by axis.
MAX_HYPOTHESES = 4000


@dataclass
class WindowProblem:
    """The window as the solver sees it: n states, n - 1 steps, m observations.

    Hard boxes are (2, n) arrays (lo row, hi row), or (2, P, n) for P pieces (a
    sub-paving: the truth lies in one of them, each a box over the whole window). ``obs`` is (7, 2, m) in the row order of
    ``localization.range_bearing``; the robot's own rows (OX, OY, OTH where ``own``,
    else AX, AY) are filled by the solver from the state boxes."""

    theta: np.ndarray  # (n,) commanded heading at each state
    dc: np.ndarray  # (n-1,) step offset bounds
    hmin: np.ndarray
    hmax: np.ndarray
    l_lo: np.ndarray
    l_hi: np.ndarray
    slack: np.ndarray
    cap: np.ndarray
    hx: np.ndarray  # (2, n) or (2, P, n) hard boxes
    hy: np.ndarray
    hth: np.ndarray
    hc: np.ndarray
    obs: np.ndarray  # (7, 2, m)
    at: np.ndarray  # (m,) state of each observation
    own: np.ndarray  # (m,) the robot is the observer (else the target)
    #: (n-1,) bound of the heading error's change inside each step (the pair condition's
    #: smaller bound, ``velocity_odometry``): a chain on the headings themselves
    dw: np.ndarray | None = None
    #: (m,) the observation each column belongs to (non-decreasing), when some are
    #: unions (a peer's pieces: one column each, the observation holds for one of them;
    #: None: one column per observation)
    group: np.ndarray | None = None

    @property
    def starts(self) -> np.ndarray | None:
        """The first column of each observation (None: one column each)."""
        if self.group is None:
            return None
        return np.flatnonzero(np.r_[True, np.diff(self.group) != 0])

    @property
    def observations(self) -> int:
        return self.at.shape[0] if self.group is None else int(self.starts.size)


@dataclass
class WindowSolution:
    x: np.ndarray  # (2, n)
    y: np.ndarray
    th: np.ndarray
    c: np.ndarray
    inconsistent: np.ndarray  # (m,) observations that broke their bounds
    empty: bool  # more than q observations (or a prior) wrong: no box
    rebased: bool  # the heading was unknown: solved by sectors, a new representation
    pieces: int  # heading pieces solved
    #: the live pieces' boxes (2, B, n) of x, y, th, c (in the representation of the
    #: hull above): the sub-paving the next solve starts from
    px: np.ndarray | None = None
    py: np.ndarray | None = None
    pth: np.ndarray | None = None
    pc: np.ndarray | None = None


def _relaxed_per_state(
    lo: np.ndarray, hi: np.ndarray, at: np.ndarray, n: int, q: int
) -> np.ndarray:
    """At each state, what all but q of its own observations' intervals (B, m) allow:
    (2, B, n)."""
    m = at.shape[0]
    out = np.empty((2,) + lo.shape[:-1] + (n,))
    out[0], out[1] = -_INF, _INF
    if m <= q:
        return out
    member = at[:, None] == np.arange(n)[None, :]
    p_lo = np.where(member, lo[..., :, None], -_INF)
    p_hi = np.where(member, hi[..., :, None], _INF)
    out[0] = np.partition(p_lo, m - 1 - q, axis=-2)[..., m - 1 - q, :]
    out[1] = np.partition(p_hi, q, axis=-2)[..., q, :]
    return out


def _hypotheses(m: int, q: int) -> np.ndarray | None:
    """The sets of q observations to leave out (H, q), or None when there are too many
    (then the relaxation is done axis by axis, ``chain.relaxed_chain_at``)."""
    if q == 0 or m == 0:
        return np.zeros((1, 0), int)
    if m <= q:
        return np.arange(m)[None, :]
    if math.comb(m, q) > MAX_HYPOTHESES:
        return None
    return np.array(list(itertools.combinations(range(m), q)), dtype=int)


def _relax(
    hard: np.ndarray, p: tuple[np.ndarray, np.ndarray], q: int, hyps: np.ndarray
) -> np.ndarray:
    """Boxes (2, B, H, n) of every hypothesis: the hard box met with the measurement
    projections ``p`` (B, m, n) it keeps."""
    lo = leave_out(p[0], q, hyps, True)
    out = np.empty((2,) + lo.shape)
    np.maximum(hard[0][:, None, :], lo, out=out[0])
    np.minimum(hard[1][:, None, :], leave_out(p[1], q, hyps, False), out=out[1])
    return out


def _solve_pieces(
    p: WindowProblem,
    hx,
    hy,
    hc,
    hth,
    hph,
    q: int,
    half_a: float,
    beta_c: float,
    iterations: int,
    tol: float,
):
    """The window for every piece at once: boxes (2, B, n), dead pieces (B,), and the
    observations proven inconsistent (B, m)."""
    b, n = hc.shape[1], p.theta.shape[0]
    at_c, own_c = p.at, p.own  # per column
    starts = p.starts
    at, own = (at_c, own_c) if starts is None else (at_c[starts], own_c[starts])
    m = at.shape[0]  # observations
    cols = np.arange(at_c.shape[0])
    rx, ry = np.where(own_c, OX, AX), np.where(own_c, OY, AY)
    o_own = np.flatnonzero(own_c)
    t_at = p.theta[at]
    hyps = _hypotheses(m, q)
    x, y = hx.copy(), hy.copy()
    th, c, ph = hth.copy(), hc.copy(), hph.copy()
    c = meet_box(c, chain_k(c[0], c[1], -p.dc, p.dc))
    obs = np.repeat(p.obs[:, :, None, :], b, axis=2)  # (7, 2, B, m)
    dcl, dch = -p.dc, p.dc
    # The heading chain: only where some step's pair bound is below what the offset
    # chain already implies (dc + a: a long turn), else it adds nothing.
    dw = p.dc + 2.0 * half_a + GUARD if p.dw is None else p.dw
    longs = bool(np.any(dw < p.dc + 2.0 * half_a))
    dh = np.diff(p.theta)
    twl, twh = K.add(dh, dh, -dw, dw)  # the heading chain's steps
    bad = np.zeros((b, m), bool)
    at_state = at[:, None] == np.arange(n)[None, :]  # (m, n)
    dead = np.zeros(b, bool)
    for _ in range(iterations):
        old = np.concatenate([x, y, c])
        tl, tu = K.add(p.theta + c[0], p.theta + c[1], -half_a - GUARD, half_a + GUARD)
        th = meet_box(th, (tl, tu))
        ph = meet_box(ph, widen_box(th, beta_c))
        th = meet_box(th, widen_box(ph, beta_c))
        if longs:
            th = meet_box(th, chain_k(th[0], th[1], twl, twh))
        wl, wh = K.add(c[0, :, :-1], c[1, :, :-1], dcl, dch)
        vl, vh = K.add(c[0, :, 1:], c[1, :, 1:], dcl, dch)
        dx_l, dx_h, dy_l, dy_h = displacements(
            p.theta[:-1], p.hmin, p.hmax, np.maximum(wl, vl), np.minimum(wh, vh),
            half_a, p.l_lo, p.l_hi, p.slack, p.cap,
            _inside(th, p.hmin, p.hmax, dh, dw) if longs else None,
        )  # fmt: skip
        x = meet_box(x, chain_k(x[0], x[1], dx_l, dx_h))
        y = meet_box(y, chain_k(y[0], y[1], dy_l, dy_h))
        dead |= any_empty(x, y, th, c) | any_empty(ph)
        if m == 0 or dead.all():
            break
        live = ~dead
        if dead.any():  # dead pieces get a harmless stand-in (kernels want non-empty operands)
            ref = int(np.argmax(live))
            for v in (x, y, th, c, ph):
                v[:, dead] = v[:, ref : ref + 1]
        obs[rx, :, :, cols] = x[:, :, at_c].transpose(2, 0, 1)
        obs[ry, :, :, cols] = y[:, :, at_c].transpose(2, 0, 1)
        obs[OTH, :, :, o_own] = ph[:, :, at_c[o_own]].transpose(2, 0, 1)
        con, bad = contract_observation(obs)
        bx = con[rx, :, :, cols].transpose(1, 2, 0)  # (2, B, columns)
        by = con[ry, :, :, cols].transpose(1, 2, 0)
        bf = np.where(own_c, con[OTH], np.array([-_INF, _INF])[:, None, None])  # camera heading
        bf = np.where(bad, np.array([_INF, -_INF])[:, None, None], bf)
        if starts is not None:  # a union's columns: the hull of those not proven empty
            bx, by, bf = (_union(v, starts) for v in (bx, by, bf))
            bad = np.logical_and.reduceat(bad, starts, axis=-1)
        bt = widen_box(bf, beta_c)
        bc = np.stack(K.sub(bt[0], bt[1], t_at - half_a - GUARD, t_at + half_a + GUARD))
        px = projections((bx[0], bx[1]), at, (dx_l, dx_h))
        py = projections((by[0], by[1]), at, (dy_l, dy_h))
        steps = (np.broadcast_to(dcl, dx_l.shape), np.broadcast_to(dch, dx_l.shape))
        pc = projections((bc[0], bc[1]), at, steps)
        pf = (
            np.where(at_state, bf[0][..., None], -_INF),
            np.where(at_state, bf[1][..., None], _INF),
        )
        if hyps is None:  # too many hypotheses: axis by axis
            x = meet_box(x, relaxed_chain_at((x[0], x[1]), (bx[0], bx[1]), at, (dx_l, dx_h), q))
            y = meet_box(y, relaxed_chain_at((y[0], y[1]), (by[0], by[1]), at, (dy_l, dy_h), q))
            c = meet_box(c, relaxed_chain_at((c[0], c[1]), (bc[0], bc[1]), at, (dcl, dch), q))
            ph = meet_box(ph, _relaxed_per_state(bf[0], bf[1], at, n, q))
            th = meet_box(th, widen_box(ph, beta_c))
            dead |= any_empty(x, y, th, c) | any_empty(ph)
        else:  # every hypothesis jointly: a state box per hypothesis, then their hull
            hx, hy = _relax(x, px, q, hyps), _relax(y, py, q, hyps)
            hcc, hf = _relax(c, pc, q, hyps), _relax(ph, pf, q, hyps)
            tl, tu = K.add(p.theta + hcc[0], p.theta + hcc[1], -half_a - GUARD, half_a + GUARD)
            ht = meet_box(meet_box(th[:, :, None, :], (tl, tu)), widen_box(hf, beta_c))
            if longs:
                ht = meet_box(ht, chain_k(ht[0], ht[1], twl, twh))
            hf = meet_box(hf, widen_box(ht, beta_c))
            hcc = meet_box(
                hcc, K.sub(ht[0], ht[1], p.theta - half_a - GUARD, p.theta + half_a + GUARD)
            )
            alive = ~(_dead4(hx) | _dead4(hy) | _dead4(hcc) | _dead4(ht) | _dead4(hf))  # (B, H)
            dead |= ~alive.any(axis=1)
            if dead.all():
                break
            x, y, c, th, ph = (_hull(v, alive) for v in (hx, hy, hcc, ht, hf))
            named = np.all(np.where(alive[:, :, None], _excluded(hyps, m)[None], True), axis=1)
            bad = bad | named
        if dead.all():
            break
        new = np.concatenate([x, y, c])
        lv = ~dead
        w_old, w_new = (old[1::2] - old[0::2])[:, lv], (new[1::2] - new[0::2])[:, lv]
        with np.errstate(invalid="ignore"):
            shrink = np.where(np.isfinite(w_old), (w_old - w_new) / np.maximum(w_old, 1e-9), 1.0)
        if float(np.max(np.nan_to_num(shrink, nan=0.0), initial=0.0)) <= tol:
            break
    return x, y, th, c, dead, bad


def _union(v: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(2, B, columns) -> (2, B, m): the hull of each observation's columns (empty
    columns, lo > hi, drop out)."""
    return np.stack(
        [np.minimum.reduceat(v[0], starts, axis=-1), np.maximum.reduceat(v[1], starts, axis=-1)]
    )


def _inside(
    th: np.ndarray, hmin: np.ndarray, hmax: np.ndarray, dh: np.ndarray, dw: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The headings inside each step from the headings of its two ends (2, B, n): within
    ``dw`` of either end's plus the commanded change since (``hmin``, ``hmax``, relative
    to the step's start; ``dh`` the whole step's)."""
    al, ah = K.add(th[0, :, :-1] + hmin, th[1, :, :-1] + hmax, -dw, dw)
    bl, bh = K.add(th[0, :, 1:] - dh + hmin, th[1, :, 1:] - dh + hmax, -dw, dw)
    return np.maximum(al, bl), np.minimum(ah, bh)


def _dead4(h: np.ndarray) -> np.ndarray:
    """(2, B, H, n) -> (B, H): some state empty."""
    return np.any(~(h[0] <= h[1]), axis=-1)


def _hull(h: np.ndarray, alive: np.ndarray) -> np.ndarray:
    """Hull over the live hypotheses (axis 2) of (2, B, H, n) -> (2, B, n)."""
    a = alive[:, :, None]
    out = np.empty((2, h.shape[1], h.shape[3]))
    np.min(np.where(a, h[0], _INF), axis=1, out=out[0])
    np.max(np.where(a, h[1], -_INF), axis=1, out=out[1])
    return out


def _excluded(hyps: np.ndarray, m: int) -> np.ndarray:
    """(H, m): whether hypothesis h leaves observation j out."""
    out = np.zeros((hyps.shape[0], m), bool)
    for col in range(hyps.shape[1]):
        out[np.arange(hyps.shape[0]), hyps[:, col]] = True
    return out


def solve_window(
    p: WindowProblem,
    q: int,
    half_a: float,
    iterations: int,
    tol: float,
    beta_c: float = 0.0,
    piece_rad: float = 0.1,
    max_pieces: int = 8,
    sectors: int = 24,
) -> WindowSolution:
    """Contract the window ``p`` with up to ``q`` observations relaxed, the newest
    camera heading cut into pieces (module doc). ``half_a`` is half the heading
    transient, ``beta_c`` the bound of the bearing error common to one instant."""
    with np.errstate(over="ignore", invalid="ignore"):
        hx, hy, hc, hth, hph, lost = heading_pieces(
            p.theta, p.dc, p.hx, p.hy, p.hth, p.hc, half_a, beta_c, piece_rad, max_pieces, sectors
        )
        x, y, th, c, dead, bad = _solve_pieces(
            p, hx, hy, hc, hth, hph, q, half_a, beta_c, iterations, tol
        )
    live = np.flatnonzero(~dead)
    m = p.observations
    b = hc.shape[1]
    if live.size == 0:
        return WindowSolution(x[:, 0], y[:, 0], th[:, 0], c[:, 0], np.ones(m, bool), True, lost, b)
    if lost:  # one representation: the circle without the largest gap between sectors
        mids = (0.5 * (hph[0, :, -1] + hph[1, :, -1]))[live]
        order = np.sort(mids)
        gaps = np.diff(np.append(order, order[0] + TWO_PI))
        start = order[(int(np.argmax(gaps)) + 1) % order.size] - np.pi / b
        s_lo, s_hi = K.two_pi_times(-np.floor((mids - start) / TWO_PI))
        th = np.stack(K.add(th[0][live], th[1][live], s_lo[:, None], s_hi[:, None]))
        c = np.stack(K.add(c[0][live], c[1][live], s_lo[:, None], s_hi[:, None]))
    else:
        th, c = th[:, live], c[:, live]
    x, y = x[:, live], y[:, live]
    hull = [np.stack([v[0].min(axis=0), v[1].max(axis=0)]) for v in (x, y, th, c)]
    return WindowSolution(*hull, np.all(bad[live], axis=0), False, lost, b, x, y, th, c)
