"""The error statistics of an MRCLAM run that the real-robot CP's default bounds
(``localization.cp_config.RangeBearingCPConfig``) are derived from, and how often each
bound is broken on that run.

    python3 bench/mrclam_errors.py [DIR] [--robots 1,2]

Against the motion-capture truth (where it exists):

- clock: bearing residual percentiles with the truth shifted by -0.1 .. 0.2 s (the
  camera lines up with the truth at zero shift; the commands lead it by the lag);
- heading: E(t) = truth heading - integrated lagged commanded turn, on a 0.02 s grid;
  over every pair of instants up to 10 s apart the residual
  |E(t1) - E(t0)| - b dt - b_m int|v| - r int|w| (b, b_m, r from the config) must stay
  below the transient a: the a that 5e-5 of the pairs exceed and the pairs above the
  configured a; the same with the long-turn fraction r2 over pairs up to 60 s apart
  (transient a2);
- path: the true displacement over 0.25 / 1 / 2 s against the commanded path length
  (along the mean heading) and sideways beyond the cone: violations of the path model;
- speeds: the largest true speed and turn rate (0.5 s), the longest command gap;
- ranges: true / measured range percentiles (landmarks, robots); the depth bounds (the
  camera reports the depth r cos(bearing)), gross misreads (bearing off by more than
  0.3 rad) left out: for landmarks the 0.05th and 99.95th percentile lines of
  depth - rho on (1, rho, rho^2) by linear quantile regression (coefficients rounded
  outward: ``range_lo_poly``, ``range_hi_poly``), for robots the factors of
  [f_lo rho - 0.02, f_hi rho + 0.02] at the same percentiles; the fraction outside the
  configured bounds (range_model and the four polynomials), with and without the
  misreads;
- bearings: the fraction of bearings that break the per-frame model (a part common to
  the frame within bearing_common_rad, each bearing within bearing_rad +
  bearing_lateral_m / range of it), the best common offset per frame chosen to break
  the fewest.

The LAST line is one JSON object with these figures.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from localization.cp_config import RangeBearingCPConfig
from localization.cp_rb_sightings import MIN_RANGE_M
from localization.mrclam import MrclamRun, load_mrclam
from numerics.angles import wrap

DEFAULT_DIR = Path(__file__).resolve().parents[2] / "shared/data/mrclam/MRCLAM_Dataset6"
GRID = 0.02
PCT = [50, 99, 99.9, 99.99, 100]


def _pct(v: np.ndarray) -> list[float]:
    return [round(float(x), 4) for x in np.percentile(v, PCT)] if v.size else []


def _targets(run: MrclamRun, r: int, m: np.ndarray, shift: float = 0.0):
    """(truth pose at the measurement, target position, ok) per measurement."""
    p, ok = run.robots[r].truth_at(m[:, 0] + shift)
    tgt = np.full((len(m), 2), np.nan)
    for i, s in enumerate(m[:, 1].astype(int)):
        if s in run.landmarks:
            tgt[i] = run.landmarks[s][:2]
        elif s in run.robots:
            q, okq = run.robots[s].truth_at(m[i, 0] + shift)
            if okq[0]:
                tgt[i] = q[0, :2]
    return p, tgt, ok & np.isfinite(tgt[:, 0])


def clock(run: MrclamRun, ids: list[int]) -> dict:
    out = {}
    for shift in (-0.1, -0.05, 0.0, 0.05, 0.1, 0.2):
        e = []
        for r in ids:
            m = run.robots[r].measurements
            p, tgt, ok = _targets(run, r, m, shift)
            b = np.arctan2(tgt[:, 1] - p[:, 1], tgt[:, 0] - p[:, 0]) - p[:, 2]
            e.append(np.abs(wrap(m[ok, 3] - b[ok])))
        out[shift] = _pct(np.concatenate(e))[:3]
    return out


def _heading_arrays(run: MrclamRun, r: int, lag: float):
    o = run.robots[r].odometry
    t, v, w = o[:, 0], o[:, 1], o[:, 2]
    tg = np.arange(t[0] + 1.0, min(t[-1], run.robots[r].truth[-1, 0]) - 1.0, GRID)
    i = np.clip(np.searchsorted(t, tg - lag, side="right") - 1, 0, len(t) - 1)
    wg, vg = w[i], v[i]
    h = np.concatenate([[0.0], np.cumsum(wg[:-1] * GRID)])
    a = np.concatenate([[0.0], np.cumsum(np.abs(wg[:-1]) * GRID)])
    dist = np.concatenate([[0.0], np.cumsum(np.abs(vg[:-1]) * GRID)])
    p, ok = run.robots[r].truth_at(tg)
    return np.unwrap(p[:, 2]) - h, a, dist, ok


#: Pair spans (grid steps) for the heading checks: every step up to 1 s, then coarser up
#: to 10 s (the transient a) and to 60 s (the long-turn bound a2).
SPANS_10S = list(range(1, 50)) + list(range(50, 500, 10))
SPANS_60S = SPANS_10S + list(range(500, 3000, 50))
#: The heading bounds' transients are set at this fraction of the pairs.
PAIR_RATE = 5e-5


def heading(run: MrclamRun, ids: list[int], cfg: RangeBearingCPConfig) -> dict:
    """The pair condition of the heading error (velocity_odometry) on every pair of
    instants: with the config's turn fraction r over spans up to 10 s (transient a), and
    with the long-turn fraction r2 over spans up to 60 s (transient a2): the transient
    each needs at ``PAIR_RATE`` of the pairs, and the pairs above the configured one."""
    out = {}
    b, bm = cfg.heading_drift_radps, cfg.heading_drift_per_m
    for name, rr, a, spans in (
        ("", cfg.heading_turn_rel, cfg.heading_transient_rad, SPANS_10S),
        ("long_", cfg.heading_turn_rel_long, cfg.heading_transient_long_rad, SPANS_60S),
    ):
        res = []
        for r in ids:
            e, turn, dist, ok = _heading_arrays(run, r, cfg.command_lag_s)
            for k in spans:
                d = np.abs(e[k:] - e[:-k]) - b * k * GRID - rr * (turn[k:] - turn[:-k])
                d -= bm * (dist[k:] - dist[:-k])
                res.append(d[ok[k:] & ok[:-k]])
        d = np.concatenate(res)
        out.update({
            f"{name}pairs": int(d.size),
            f"{name}pairs_over_a": int((d > a).sum()),
            f"{name}a_at_rate": round(float(np.quantile(d, 1.0 - PAIR_RATE)), 4),
            f"{name}residual_max": round(float(d.max()), 4),
        })  # fmt: skip
    return out


def path(run: MrclamRun, ids: list[int], cfg: RangeBearingCPConfig) -> dict:
    out = {}
    for span in (0.25, 1.0, 2.0):
        n = bad = 0
        for r in ids:
            rb = run.robots[r]
            o = rb.odometry
            t, v = o[:, 0], o[:, 1]
            cs = np.concatenate([[0.0], np.cumsum(v[:-1] * np.diff(t))])

            def integ(tq, t=t, cs=cs, v=v):
                i = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, len(t) - 1)
                return cs[i] + v[i] * (tq - t[i])

            t0 = np.arange(t[0] + 1.0, t[-1] - span - 1.0, span)
            poses, ok = [], np.ones(t0.size, bool)
            for f in np.linspace(0.0, 1.0, 11):
                p, okf = rb.truth_at(t0 + f * span)
                poses.append(p)
                ok &= okf
            poses = np.array(poses)
            th = np.unwrap(poses[:, :, 2], axis=0)
            mid, half = 0.5 * (th.max(0) + th.min(0)), 0.5 * (th.max(0) - th.min(0))
            d = poses[-1, :, :2] - poses[0, :, :2]
            along = d[:, 0] * np.cos(mid) + d[:, 1] * np.sin(mid)
            side = np.abs(-d[:, 0] * np.sin(mid) + d[:, 1] * np.cos(mid)) - np.abs(along) * np.sin(
                half
            )
            s = integ(t0 + span - cfg.command_lag_s) - integ(t0 - cfg.command_lag_s)
            p_abs = cfg.path_abs_m + cfg.path_drift_mps * span
            l_hi = (1 + cfg.speed_rel_hi) * s + p_abs
            l_lo = np.maximum(0.0, (1 - cfg.speed_rel_lo) * s - p_abs)
            slack = cfg.slack_abs_m + cfg.slack_drift_mps * span
            viol = (along > l_hi + slack) | (along < l_lo - slack) | (side > slack)
            n += int(ok.sum())
            bad += int((viol & ok).sum())
        out[span] = {"spans": n, "violations": bad}
    return out


def speeds(run: MrclamRun, ids: list[int]) -> dict:
    v, w, gap = 0.0, 0.0, 0.0
    for r in ids:
        rb = run.robots[r]
        tg = np.arange(rb.truth[0, 0] + 1, rb.truth[-1, 0] - 1, 0.5)
        p, ok = rb.truth_at(tg)
        ok2 = ok[1:] & ok[:-1]
        v = max(v, float((np.hypot(*np.diff(p[:, :2], axis=0).T) / 0.5)[ok2].max()))
        w = max(w, float((np.abs(wrap(np.diff(p[:, 2]))) / 0.5)[ok2].max()))
        gap = max(gap, float(np.diff(rb.odometry[:, 0]).max()))
    return {"speed_max_mps": v, "turn_rate_max_radps": w, "command_gap_max_s": gap}


#: A sighting whose bearing is off by more than this is a gross misread (a barcode read
#: as another subject): left out of the bounds' percentiles (the q-relaxation's job),
#: counted in the fractions outside them.
MISREAD_RAD = 0.3
#: Robots' depth bound: the factors at this offset (their tails are misreads).
ROBOT_ABS_M = 0.02


def quantile_line(x: np.ndarray, y: np.ndarray, tau: float, degree: int = 2) -> np.ndarray:
    """Linear quantile regression (Koenker): coefficients c (c0, c1, ...) of the
    polynomial in ``x`` below which a fraction ``tau`` of ``y`` lies (the pinball loss
    minimised as a linear program)."""
    from scipy import sparse
    from scipy.optimize import linprog

    X = np.column_stack([x**k for k in range(degree + 1)])
    n, p = X.shape
    c = np.concatenate([np.zeros(p), np.full(n, tau), np.full(n, 1.0 - tau)])
    eye = sparse.identity(n, format="csr")
    a = sparse.hstack([sparse.csr_matrix(X), eye, -eye], format="csr")
    bounds = [(None, None)] * p + [(0.0, None)] * (2 * n)
    res = linprog(c, A_eq=a, b_eq=y, bounds=bounds, method="highs")
    if not res.success:
        raise RuntimeError(f"quantile regression failed: {res.message}")
    return res.x[:p]


def _outward(c: np.ndarray, up: bool, digits: int = 4) -> list[float]:
    """Coefficients rounded outward (for r >= 0 every term moves the same way)."""
    f = np.ceil if up else np.floor
    return [float(f(v * 10**digits) / 10**digits) for v in c]


def _poly(c, r: np.ndarray) -> np.ndarray:
    return c[0] + r * (c[1] + r * c[2])


def ranges_and_bearings(run: MrclamRun, ids: list[int], cfg: RangeBearingCPConfig) -> dict:
    cols = {"landmark": [], "robot": []}  # (true range, measured, bearing measured, misread)
    frames = []
    for r in ids:
        m = run.robots[r].measurements
        p, tgt, ok = _targets(run, r, m)
        true = np.hypot(tgt[:, 0] - p[:, 0], tgt[:, 1] - p[:, 1])
        e = wrap(m[:, 3] - (np.arctan2(tgt[:, 1] - p[:, 1], tgt[:, 0] - p[:, 0]) - p[:, 2]))
        lm = np.isin(m[:, 1].astype(int), list(run.landmarks))
        for kind, sel in (("landmark", ok & lm), ("robot", ok & ~lm)):
            cols[kind].append(
                np.column_stack([true, m[:, 2], m[:, 3], np.abs(e) > MISREAD_RAD])[sel]
            )
        for t in np.unique(m[ok, 0]):
            f = ok & (m[:, 0] == t)
            frames.append((e[f], m[f, 2]))
    out = {}
    ab = ROBOT_ABS_M
    for kind, v in cols.items():
        true, rho, psi, bad = np.concatenate(v).T
        bad = bad > 0
        good = ~bad
        depth = true * np.cos(psi)
        lo_p, hi_p = (
            (cfg.robot_range_lo_poly, cfg.robot_range_hi_poly)
            if kind == "robot"
            else (cfg.range_lo_poly, cfg.range_hi_poly)
        )
        out[f"{kind}_sightings"] = int(true.size)
        out[f"{kind}_misreads"] = int(bad.sum())
        out[f"{kind}_range_true_over_measured_pct_0.05_99.95"] = [
            round(float(x), 4) for x in np.percentile(true[good] / rho[good], [0.05, 99.95])
        ]
        if kind == "landmark":  # quadratic 0.05th / 99.95th percentile lines of d - rho
            e = depth[good] - rho[good]
            lo_c = quantile_line(rho[good], e, 0.0005)
            hi_c = quantile_line(rho[good], e, 0.9995)
            out["landmark_depth_poly_lo_hi"] = [_outward(lo_c, False), _outward(hi_c, True)]
            out["landmark_depth_poly_width_at_1_2_3_4_5_7_m"] = [
                round(float(_poly(hi_c, r) - _poly(lo_c, r)), 3) for r in (1, 2, 3, 4, 5, 7)
            ]
        else:  # robots: true depth in [f_lo rho - abs, f_hi rho + abs] for 99.9 %
            out[f"robot_depth_factors_abs_{ab}_pct_0.05_99.95"] = [
                round(float(np.percentile((depth[good] + ab) / rho[good], 0.05)), 4),
                round(float(np.percentile((depth[good] - ab) / rho[good], 99.95)), 4),
            ]
        x = depth if cfg.range_model == "depth" else true
        outside = (x < rho + _poly(lo_p, rho)) | (x > rho + _poly(hi_p, rho))
        out[f"{kind}_range_outside"] = float(np.mean(outside))
        out[f"{kind}_range_outside_not_misread"] = float(np.mean(outside[good]))
    bc = cfg.bearing_common_rad
    broken = 0
    for e, rho in frames:
        br = cfg.bearing_rad + cfg.bearing_lateral_m / np.maximum(rho, MIN_RANGE_M)
        cands = np.clip(np.concatenate([e - br, e + br, [0.0]]), -bc, bc)
        broken += min(int(np.sum(np.abs(e - c) > br)) for c in cands)
    n = sum(len(f[0]) for f in frames)
    out.update(frames=len(frames), bearings=n, bearings_breaking_frame_model=broken)
    out["bearing_outside_fraction"] = broken / max(n, 1)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir", nargs="?", default=str(DEFAULT_DIR))
    ap.add_argument("--robots", default=None)
    args = ap.parse_args(argv)
    robots = [int(r) for r in args.robots.split(",")] if args.robots else None
    run = load_mrclam(args.dir, robots)
    ids = sorted(run.robots)
    cfg = RangeBearingCPConfig()
    out = {
        "run": Path(args.dir).name,
        "clock_bearing_pct_50_99_999_by_truth_shift": clock(run, ids),
        "heading": heading(run, ids, cfg),
        "path": path(run, ids, cfg),
        **speeds(run, ids),
        **ranges_and_bearings(run, ids, cfg),
    }
    for k, v in out.items():
        print(f"{k:>45}: {v}")
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
