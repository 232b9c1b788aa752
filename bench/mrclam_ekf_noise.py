"""The error statistics the MRCLAM EKF's defaults are derived from, on any MRCLAM run.

localization/mrclam_config.py's defaults come from Dataset 6 through the steps below
(docs/algorithms.md, "EKF on the MRCLAM robots"); run on another run directory of the
same kind, this prints the same statistics next to the defaults, so that they can be
checked there rather than tuned. Against the motion-capture truth (``truth_at``,
measurements with |range error| < 30 % and |bearing error| < 0.3 rad; the gross outliers
are the gate's business):

1. the range error / range by bearing, raw and under the depth model (range = depth along
   the optical axis = r cos(bearing)): the camera model;
2. a least-squares fit of the camera terms, per robot g = 1 + c + e psi + q psi^2 and the
   offsets d of landmarks and robots, rho = g r cos(psi) + d, and the residual sigmas
   (p95 / 1.96) by range, range and bearing: the noise model;
3. the autocorrelation of the normalised residuals, of one target (same) and of two
   (other), by lag: the white part (1 - same at the shortest lag), the part common to
   all targets (other) and the per-target part (same - other), with their integral time
   scales, and the zero-lag correlation within a camera frame;
4. the heading error of the commanded turn rate (0.18 s lag) over windows, by the angle
   turned S: the turn scale error per robot (its rms: the prior sigma of the turn scale
   state), and without it the p95 by S: var = w_noise_turn S (the median over the bins).

The LAST line is a JSON object with the derived values.

    python3 bench/mrclam_ekf_noise.py [DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from localization.mrclam import MrclamRun, load_mrclam
from localization.mrclam_config import MrclamEkfConfig
from numerics.angles import wrap

DEFAULT_DIR = Path(__file__).resolve().parents[2] / "shared/data/mrclam/MRCLAM_Dataset6"
LAG_EDGES = np.array([0.0, 0.011, 0.3, 0.6, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0])
RANGE_BINS = (0.0, 1.5, 2.5, 3.5, 4.5, 8.0)


def measurements(run: MrclamRun) -> np.ndarray:
    """Rows (robot, time, subject, range, bearing, true range, true bearing)."""
    rows = []
    for n, rr in run.robots.items():
        m = rr.measurements
        pose, ok = rr.truth_at(m[:, 0])
        target = np.full((len(m), 2), np.nan)
        for i, s in enumerate(m[:, 1].astype(int)):
            if s in run.landmarks:
                target[i] = run.landmarks[s][:2]
            elif s in run.robots and s != n:
                p, o = run.robots[s].truth_at(m[i, 0])
                if o[0]:
                    target[i] = p[0, :2]
        d = target - pose[:, :2]
        rt = np.hypot(d[:, 0], d[:, 1])
        bt = wrap(np.arctan2(d[:, 1], d[:, 0]) - pose[:, 2])
        keep = ok & np.isfinite(rt)
        rows.append(np.column_stack([np.full(len(m), n), m[:, :4], rt, bt])[keep])
    return np.concatenate(rows)


def camera_fit(a: np.ndarray, robots: list[int]) -> dict:
    """Step 2: per robot (c, e, q), offsets d of landmarks and robots; residuals."""
    n, _, s, r, b, rt, _ = a.T
    depth = rt * np.cos(b)
    cols = []
    for k in robots:
        m = n == k
        cols += [depth * m, depth * b * m, depth * b * b * m]
    lm = s > max(robots)
    cols += [lm.astype(float), (~lm).astype(float)]
    coef, *_ = np.linalg.lstsq(np.column_stack(cols), r - depth, rcond=None)
    res = r - depth - np.column_stack(cols) @ coef
    per = {k: [round(float(v), 4) for v in coef[3 * i : 3 * i + 3]] for i, k in enumerate(robots)}
    return {"per_robot_c_e_q": per, "d_landmark": coef[-2], "d_robot": coef[-1], "res": res}


def acf(x: np.ndarray, t: np.ndarray, subj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean products of x (unit variance) by lag bin, same target and other targets."""
    nb = len(LAG_EDGES) - 1
    same, n_same, other, n_other = (np.zeros(nb) for _ in range(4))
    ends = np.searchsorted(t, t + LAG_EDGES[-1])
    for i in range(len(x)):
        j = np.arange(i + 1, ends[i])
        if not len(j):
            continue
        k = np.searchsorted(LAG_EDGES, t[j] - t[i], side="right") - 1
        p = x[i] * x[j]
        eq = subj[j] == subj[i]
        same += np.bincount(k[eq], p[eq], nb)
        n_same += np.bincount(k[eq], minlength=nb)
        other += np.bincount(k[~eq], p[~eq], nb)
        n_other += np.bincount(k[~eq], minlength=nb)
    return same / np.maximum(n_same, 1), other / np.maximum(n_other, 1)


def integral_scale(c: np.ndarray) -> float:
    """Integral of a correlation (by LAG_EDGES bins, from the second) up to its first
    non-positive bin, over its value at the shortest lag."""
    w = np.diff(LAG_EDGES)
    total = 0.0
    for k in range(1, len(c)):
        if c[k] <= 0.0:
            break
        total += c[k] * w[k]
    return total / c[1] if c[1] > 0 else float("nan")


def correlation(a: np.ndarray, z: np.ndarray, robots: list[int]) -> dict:
    """Step 3 for one residual z (range or bearing), pooled over the robots."""
    same = np.zeros(len(LAG_EDGES) - 1)
    other = same.copy()
    for k in robots:
        m = a[:, 0] == k
        x = z[m] - z[m].mean()
        s, o = acf(x / x.std(), a[m, 1], a[m, 2])
        same += s / len(robots)
        other += o / len(robots)
    return {
        "same": np.round(same, 3).tolist(),
        "other": np.round(other, 3).tolist(),
        "white": round(1.0 - same[1], 3),
        "common": round(other[1], 3),
        "common_scale_s": round(integral_scale(other), 1),
        "target": round(same[1] - other[1], 3),
        "target_scale_s": round(integral_scale(same - other), 1),
        "frame_correlation": round(other[0], 3),
    }


def heading_drift(run: MrclamRun, lag: float = 0.18) -> dict:
    """Step 4: heading error over windows by angle turned; turn scale per robot."""
    errs, turned, signed, robot = [], [], [], []
    for w in (5.0, 10.0, 20.0):
        for n, rr in run.robots.items():
            o = rr.odometry
            tc = o[:, 0] + lag
            dt = np.diff(tc)
            cum = np.concatenate([[0.0], np.cumsum(o[:-1, 2] * dt)])
            cum_abs = np.concatenate([[0.0], np.cumsum(np.abs(o[:-1, 2]) * dt)])
            grid = np.arange(tc[0] + 1.0, tc[-1] - w - 1.0, w)
            pa, oka = rr.truth_at(grid)
            pb, okb = rr.truth_at(grid + w)
            ok = oka & okb
            cmd = (np.interp(grid + w, tc, cum) - np.interp(grid, tc, cum))[ok]
            errs.append(wrap(pb[ok, 2] - pa[ok, 2] - cmd))
            turned.append((np.interp(grid + w, tc, cum_abs) - np.interp(grid, tc, cum_abs))[ok])
            signed.append(cmd)
            robot.append(np.full(ok.sum(), n))
    e, s, c, rb = (np.concatenate(x) for x in (errs, turned, signed, robot))
    scale = {int(n): float(np.sum(e[rb == n] * c[rb == n]) / np.sum(c[rb == n] ** 2))
             for n in run.robots}  # fmt: skip
    e0 = e - np.array([scale[int(n)] for n in rb]) * c  # without each robot's turn scale
    bins = ((0.0, 0.02), (0.2, 0.5), (0.5, 1.0), (1.0, 2.0), (2.0, 5.0))
    p95, q = {}, []
    for lo, hi in bins:
        m = (s >= lo) & (s < hi)
        if m.sum() > 20:
            p95[f"{lo}-{hi}"] = [round(float(np.percentile(np.abs(x[m]), 95)), 3)
                                 for x in (e, e0)] + [int(m.sum())]  # fmt: skip
            if lo > 0.0:  # var = q S: sigma^2 = (p95 / 1.96)^2 over the median angle
                q.append((np.percentile(np.abs(e0[m]), 95) / 1.96) ** 2 / np.median(s[m]))
    k = np.array(list(scale.values()))
    return {
        "p95_by_turn": p95,
        "w_noise_turn": float(np.median(q)) if q else float("nan"),
        "turn_scale_sigma": float(np.sqrt(np.mean(k**2))),
        "turn_scale_per_robot": {n: round(v, 3) for n, v in scale.items()},
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("directory", nargs="?", default=str(DEFAULT_DIR))
    args = ap.parse_args()
    run = load_mrclam(args.directory)
    robots = sorted(run.robots)
    cfg = MrclamEkfConfig()
    a = measurements(run)
    n, t, s, r, b, rt, bt = a.T
    eb = wrap(b - bt)
    a = a[(np.abs(r / rt - 1.0) < 0.3) & (np.abs(eb) < 0.3)]
    n, t, s, r, b, rt, bt = a.T
    eb = wrap(b - bt)
    lm = s > max(robots)
    print(f"{Path(args.directory).name}: {len(a)} measurements ({lm.sum()} of landmarks)")
    print("1. range error / range by bearing (landmarks): raw, depth model (r cos psi)")
    edges = np.arange(-0.6, 0.61, 0.2)
    k = np.digitize(b, edges)
    for j in range(1, len(edges)):
        m = lm & (k == j)
        if m.sum() > 20:
            raw, dep = r[m] / rt[m] - 1.0, r[m] / (rt[m] * np.cos(b[m])) - 1.0
            print(f"   bearing {edges[j - 1]:+.1f}..{edges[j]:+.1f}: raw {np.mean(raw):+.3f}, "
                  f"depth {np.mean(dep):+.3f}  ({m.sum()})")  # fmt: skip
    fit = camera_fit(a, robots)
    res = fit.pop("res")
    print(f"2. camera terms per robot (c, e, q): {fit['per_robot_c_e_q']}")
    print(f"   offsets: landmarks {fit['d_landmark']:.3f} m, robots {fit['d_robot']:.3f} m "
          f"(difference {fit['d_robot'] - fit['d_landmark']:.3f}, default "
          f"{cfg.robot_target_offset_m})")  # fmt: skip
    beta = np.array([np.mean(eb[lm & (n == q)]) for q in robots])
    print(f"   mean bearing error per robot (beta): {np.round(beta, 4).tolist()}")
    eb0 = eb - beta[np.searchsorted(robots, n)]
    sig_r, sig_b = [], []
    for lo, hi in zip(RANGE_BINS[:-1], RANGE_BINS[1:], strict=True):
        m = lm & (rt >= lo) & (rt < hi)
        sr = np.percentile(np.abs(res[m]), 95) / 1.96
        sb = np.percentile(np.abs(eb0[m]), 95) / 1.96
        r0 = float(np.median(rt[m]))
        mr = np.sqrt(cfg.range_sigma_m**2 + (cfg.range_sigma_quad * r0 * r0) ** 2)
        mb = np.sqrt(cfg.bearing_sigma_rad**2 + (cfg.bearing_sigma_lateral_m / r0) ** 2)
        sig_r.append(round(float(sr), 4))
        sig_b.append(round(float(sb), 4))
        print(f"   range {lo}-{hi} m: range sigma {sr:.4f} (model {mr:.4f}), "
              f"bearing sigma {sb:.4f} (model {mb:.4f})  ({m.sum()})")  # fmt: skip
    sr_model = np.sqrt(cfg.range_sigma_m**2 + (cfg.range_sigma_quad * rt**2) ** 2)
    corr = {
        "range": correlation(a[lm], (res / sr_model)[lm], robots),
        "bearing": correlation(a[lm], eb0[lm], robots),
    }
    print("3. correlation of the residuals (landmarks): lag bins (s)", LAG_EDGES[:-1].tolist())
    for name, c in corr.items():
        print(f"   {name}: same target {c['same']}")
        print(f"   {name}: other targets {c['other']}")
        print(f"   {name}: white {c['white']}, common {c['common']} (scale "
              f"{c['common_scale_s']} s), per target {c['target']} (scale "
              f"{c['target_scale_s']} s), same frame {c['frame_correlation']}")  # fmt: skip
    r3 = 3.0  # a typical range: the common errors' sigmas there (range relative)
    sr3 = np.sqrt(cfg.range_sigma_m**2 + (cfg.range_sigma_quad * r3 * r3) ** 2) / r3
    sb3 = np.sqrt(cfg.bearing_sigma_rad**2 + (cfg.bearing_sigma_lateral_m / r3) ** 2)
    derived = {
        "error_white_fraction": (corr["range"]["white"], corr["bearing"]["white"]),
        "error_target_fraction": (corr["range"]["target"], corr["bearing"]["target"]),
        "error_correlation_s": (corr["range"]["target_scale_s"], corr["bearing"]["target_scale_s"]),
        "camera_common_sigma": (round(float(np.sqrt(max(corr["range"]["common"], 0.0)) * sr3), 4),
                                round(float(np.sqrt(max(corr["bearing"]["common"], 0.0)) * sb3), 4)),
        "camera_common_tau_s": (corr["range"]["common_scale_s"], corr["bearing"]["common_scale_s"]),
        "frame_correlation": tuple(
            round((c["frame_correlation"] - c["common"]) / c["white"], 2) for c in corr.values()
        ),
    }  # fmt: skip
    derived = {k: tuple(float(x) for x in v) for k, v in derived.items()}
    for key, v in derived.items():
        print(f"   -> {key} {v} (default {getattr(cfg, key)})")
    head = heading_drift(run)
    print(
        "4. heading error p95 (rad; 5, 10, 20 s windows) by angle turned (rad): raw, "
        f"without each robot's turn scale, count: {head['p95_by_turn']}"
    )
    print(f"   fit: w_noise_turn {head['w_noise_turn']:.4f} (default {cfg.w_noise_turn}), "
          f"turn_scale_sigma {head['turn_scale_sigma']:.3f} (default {cfg.turn_scale_sigma}); "
          f"turn scale per robot {head['turn_scale_per_robot']}")  # fmt: skip
    out = {
        "directory": Path(args.directory).name,
        "camera": {
            k: (round(float(v), 4) if not isinstance(v, dict) else v) for k, v in fit.items()
        },  # fmt: skip
        "bearing_offset_per_robot": np.round(beta, 4).tolist(),
        "range_sigma_by_range": sig_r,
        "bearing_sigma_by_range": sig_b,
        "range_bins_m": list(RANGE_BINS),
        "correlation": {
            k: {q: v for q, v in c.items() if q not in ("same", "other")} for k, c in corr.items()
        },  # fmt: skip
        "heading": {
            k: (round(float(v), 4) if not isinstance(v, dict) else v) for k, v in head.items()
        },  # fmt: skip
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
