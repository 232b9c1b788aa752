"""The heading pieces of the real-robot window solver (``localization.cp_rb_solve``):
the newest camera heading cut into slices, or into sectors of the circle when it is
unknown, each slice with its own boxes over the window.

**Heading pieces.** Boxes lose the coupling of heading and position: a heading interval
of width w turns every range-bearing observation at range r into a box some r w wide,
and with the heading unknown a bearing says nothing at all. So the newest state's
heading is cut into pieces no wider than ``piece_rad`` (a one-dimensional paving), the
window is solved for every piece at once (a batch axis through every array), and the
results of the pieces not proven empty are joined (hull). Sound: every solution lies in
some piece, and that piece's solve keeps it.

**A sub-paving kept across solves.** The live pieces' boxes over the whole window are
returned too (``WindowSolution.px`` ...), and the caller hands them back as the next
problem's hard boxes, (2, P, n) for P pieces. The next solve cuts the range of their
newest camera headings into slices and starts each slice from the hull of the pieces
whose newest camera heading meets it (:func:`heading_pieces`), so a heading slice keeps
its own position boxes from one solve to the next rather than the hull's.

**Headings that recover.** Headings are real intervals in one representation (shifting
all of them by 2 pi k changes nothing). When the newest offset is almost a whole turn
wide (lost, or never known), the pieces are sectors of [-pi, pi) instead: any solution
has a 2 pi k shift whose newest heading lies in one of them. Each sector carries its own
representation along the chains (the heading priors are met with it on every 2 pi
branch), so every bearing meets it on one branch, and the window's observations rule
out the sectors they cannot all (but q) agree with. The survivors are joined in the
representation that leaves out the largest gap of the circle between them.
"""

from __future__ import annotations

import numpy as np

from localization import interval_kernels as K
from localization.chain import chain_k
from localization.interval import IV, meet_angle
from localization.interval_trig import TWO_PI
from localization.velocity_odometry import GUARD

_INF = np.inf
#: A newest offset wider than this: the heading is unknown; solve by sectors.
LOST_WIDTH = TWO_PI - 0.5


def meet_box(a: np.ndarray, b) -> np.ndarray:
    out = np.empty(np.broadcast_shapes(np.shape(a), (2,) + np.shape(b[0])))
    if out.ndim == 1:
        return np.array([max(a[0], b[0]), min(a[1], b[1])])
    np.maximum(a[0], b[0], out=out[0])
    np.minimum(a[1], b[1], out=out[1])
    return out


def any_empty(*boxes: np.ndarray) -> np.ndarray:
    """Per piece (axis 1 of (2, B, n) boxes): some box is empty."""
    out = np.zeros(boxes[0].shape[1], bool)
    for b in boxes:
        out |= np.any(~(b[0] <= b[1]), axis=-1)
    return out


def _offset_of(th: np.ndarray, theta: np.ndarray, half_a: float) -> np.ndarray:
    """Offsets c = th - Theta - s, |s| <= half_a."""
    return np.stack(K.sub(th[0], th[1], theta - half_a - GUARD, theta + half_a + GUARD))


def widen_box(b: np.ndarray, r: float) -> np.ndarray:
    out = np.empty(np.shape(b))
    out[0], out[1] = K.add(b[0], b[1], -r, r)
    return out


def _as_pieces(b: np.ndarray) -> np.ndarray:
    """Hard boxes as (2, P, n)."""
    return b[:, None, :] if b.ndim == 2 else b


def _hull_over(v: np.ndarray, member: np.ndarray) -> np.ndarray:
    """(2, P, n) boxes -> (2, B, n): per row of ``member`` (B, P), the hull of its
    members."""
    m = member[:, :, None]
    return np.stack(
        [
            np.min(np.where(m, v[0][None], _INF), axis=1),
            np.max(np.where(m, v[1][None], -_INF), axis=1),
        ]
    )


def heading_pieces(
    theta: np.ndarray,
    dc: np.ndarray,
    hx: np.ndarray,
    hy: np.ndarray,
    hth: np.ndarray,
    hc: np.ndarray,
    half_a: float,
    beta_c: float,
    piece_rad: float,
    max_pieces: int,
    sectors: int,
):
    """The hard boxes (2, B, n) of x, y, the offsets, headings and camera headings of
    every piece of the newest camera heading, and whether the pieces are sectors. The
    hard boxes hx, hy, hth, hc are (2, n) or (2, P, n); theta (n,) the commanded headings,
    dc (n - 1,) the offset chain's steps.

    The problem's own pieces (P of them, each a box over the window: the sub-paving
    kept from the previous solve) are the parents: the range of their newest camera
    headings is cut into B slices of at most ``piece_rad`` (at most ``max_pieces``), and
    each slice gets the hull of the parents whose newest camera heading meets it. Every
    solution lies in a parent and its newest camera heading in one of the slices that
    parent meets, so the slices cover every solution."""
    hx, hy, hth, hc = (_as_pieces(v) for v in (hx, hy, hth, hc))
    n = theta.shape[0]
    k = n - 1
    c0 = meet_box(hc, _offset_of(hth, theta, half_a))
    c0 = meet_box(c0, chain_k(c0[0], c0[1], -dc, dc))
    t0 = meet_box(
        hth[:, :, k],
        K.add(theta[k] + c0[0, :, k], theta[k] + c0[1, :, k], -half_a - GUARD, half_a + GUARD),
    )
    f0 = widen_box(t0, beta_c)
    ok = (f0[0] <= f0[1]) & ~any_empty(hx, hy, hth, c0)
    if not ok.any():
        ok[0] = True  # every parent is empty: solve one, which comes out dead
    hx, hy, hth, c0, f0 = hx[:, ok], hy[:, ok], hth[:, ok], c0[:, ok], f0[:, ok]
    lost = not float(np.max(c0[1, :, k]) - np.min(c0[0, :, k])) < LOST_WIDTH
    if not lost:
        fl, fh = f0[0], f0[1]
        f_lo, f_hi = float(np.min(fl)), float(np.max(fh))
        b = int(min(max(np.ceil((f_hi - f_lo) / piece_rad), 1), max_pieces))
        e = f_lo + (f_hi - f_lo) * np.arange(b + 1) / b
        lo, hi = np.maximum(K.down(e[:-1]), f_lo), np.minimum(K.up(e[1:]), f_hi)
        lo[0], hi[-1] = f_lo, f_hi
        member = (fl[None, :] <= hi[:, None]) & (fh[None, :] >= lo[:, None])  # (b, P)
        keep = member.any(axis=1)
        member, lo, hi = member[keep], lo[keep], hi[keep]
        b = int(keep.sum())
        lo = np.maximum(lo, np.min(np.where(member, fl[None, :], _INF), axis=1))
        hi = np.minimum(hi, np.max(np.where(member, fh[None, :], -_INF), axis=1))
        hx, hy, hc, hth = (_hull_over(v, member) for v in (hx, hy, c0, hth))
    else:
        # Sectors of [-pi, pi) for the newest camera heading; every hard heading box met
        # with each sector's representation (carried along the chain) on every branch.
        one = np.ones((1, hx.shape[1]), bool)
        hx, hy, p_hc, p_hth = (_hull_over(v, one)[:, 0] for v in (hx, hy, c0, hth))
        b = sectors
        hx, hy = np.repeat(hx[:, None, :], b, axis=1), np.repeat(hy[:, None, :], b, axis=1)
        e = -np.pi + TWO_PI * np.arange(b + 1) / b
        lo, hi = K.down(e[:-1] - 1e-9), K.up(e[1:] + 1e-9)
        anchor = np.empty((2, b, n))
        anchor[0], anchor[1] = -_INF, _INF
        tl, th = K.add(lo, hi, -beta_c, beta_c)
        anchor[:, :, k] = K.sub(tl, th, theta[k] - half_a - GUARD, theta[k] + half_a + GUARD)
        hc = meet_box(np.stack(chain_k(anchor[0], anchor[1], -dc, dc)), anchor)
        hth = np.stack(K.add(theta + hc[0], theta + hc[1], -half_a - GUARD, half_a + GUARD))
        for h, ph in ((hc, p_hc), (hth, p_hth)):
            fin = np.isfinite(ph[0]) & np.isfinite(ph[1])
            if fin.any():
                met = meet_angle(IV(h[0][:, fin], h[1][:, fin]), IV(ph[0, fin], ph[1, fin]))
                h[0][:, fin], h[1][:, fin] = met.lo, met.hi
    hph = np.empty((2, b, n))
    hph[0], hph[1] = -_INF, _INF
    hph[0, :, k], hph[1, :, k] = lo, hi
    tl, th = K.add(lo, hi, -beta_c, beta_c)
    hth[0, :, k], hth[1, :, k] = np.maximum(hth[0, :, k], tl), np.minimum(hth[1, :, k], th)
    cl, ch = K.sub(tl, th, theta[k] - half_a - GUARD, theta[k] + half_a + GUARD)
    hc[0, :, k], hc[1, :, k] = np.maximum(hc[0, :, k], cl), np.minimum(hc[1, :, k], ch)
    return hx, hy, hc, hth, hph, lost
