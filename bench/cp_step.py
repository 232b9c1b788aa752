"""Benchmark: the CP localizer's one-box-per-step case (the daemon's and every ``hilnav
fleet`` robot's), the array path against the scalar fast path (localization.cp_scalar),
side by side in one run.

- ``contraction``: one range-bearing contraction of one box against one peer
  (``contractors.contract_range_bearing`` on 0-d interval arrays vs
  ``cp_scalar.contract_range_bearing`` on floats), over seeded random robot-sized boxes
  around a true configuration;
- ``relative``: ``CPLocalizer.feed_relatives`` (every peer at once, fixpoint, meet into
  the window) as the paper scenario's cooperative robots call it;
- ``window_solve``: one solve of the sliding window (``SlidingWindowCP._solve``: the
  array solve of ``cp_solve`` against the incremental one of ``cp_incremental``);
- ``step``: CPU per robot-step of the whole cooperative loop (own sensors, window
  solve, peers' boxes, relative measurements, 3 robots);
- ``daemon``: the daemon's CP service (``hilnav.services.LocalizationAdapter``) with
  the default settings (window 40, 2 GPS outliers tolerated) on one robot of the same
  scenario with a fix every 10th step (GPS at 1 Hz, odometry at 10 Hz): CPU per
  odometry step of the service, and of its window solve.

The paper scenario is the simulator's (fakes.world.paper_scenario, uniform errors);
the boxes of both paths are compared (largest bound difference, and the most the
scalar path's box is wider than the array path's: never, up to rounding) and their
containment of the truth printed. A table, and the LAST line is one JSON object
(figures in µs, the machine's load average at the start and end).

    python bench/cp_step.py [--duration 20] [--window 40] [--seed 0] [--n 300]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import localization.cp_scalar as cps
import localization.interval_scalar as isc
from fakes.world.paper_scenario import paper_robots, simulate
from hilnav.config import config_data, load_config, parse_config
from hilnav.fleet.paper import PaperDevices, PaperRobot
from hilnav.services import LocalizationAdapter
from localization.contractors import contract_range_bearing
from localization.cp_window import SlidingWindowCP
from localization.interval import IV


def _boxes(rng: np.random.Generator) -> list[tuple[float, float]]:
    xi, yi, thi = rng.uniform(-10, 10), rng.uniform(-10, 10), rng.uniform(-4, 4)
    rho, beta = rng.uniform(0.5, 15), rng.uniform(-math.pi, math.pi)
    truth = (xi, yi, thi, xi + rho * math.cos(thi + beta), yi + rho * math.sin(thi + beta))
    truth += (rho, beta)
    out = []
    for v, w in zip(truth, (0.5, 0.5, 0.05, 0.5, 0.5, 0.1, 0.05), strict=True):
        r = w * rng.uniform(0.2, 1.0)
        off = rng.uniform(-r, r)
        out.append((v + off - r, v + off + r))
    return out


def contraction_us(n: int, seed: int) -> tuple[float, float]:
    rng = np.random.default_rng(seed)
    cases = [_boxes(rng) for _ in range(n)]
    ivs = [[IV.of(lo, hi) for lo, hi in c] for c in cases]
    t0 = time.process_time()
    for c in ivs:
        contract_range_bearing(*c)
    t1 = time.process_time()
    for c in cases:
        try:
            cps.contract_range_bearing(*c)
        except isc.Fallback:
            pass
    t2 = time.process_time()
    return (t1 - t0) / n * 1e6, (t2 - t1) / n * 1e6


class _Timer:
    """CPU time of the window solves (wrapping SlidingWindowCP._solve; a solve that
    returns the kept solution is not counted)."""

    def __init__(self) -> None:
        self.solve_s, self.solves = 0.0, 0
        self._orig = SlidingWindowCP._solve

    def __enter__(self) -> _Timer:
        orig = self._orig

        def timed(loc):
            if not loc._dirty and loc._sol is not None:
                return loc._sol
            t = time.process_time()
            out = orig(loc)
            self.solve_s += time.process_time() - t
            self.solves += 1
            return out

        SlidingWindowCP._solve = timed  # type: ignore[method-assign]
        return self

    def __exit__(self, *exc) -> None:
        SlidingWindowCP._solve = self._orig  # type: ignore[method-assign]


def scenario(sc, window: int, scalar: bool) -> dict:
    SlidingWindowCP.scalar_path = scalar
    robots = [PaperRobot(sc, i, window=window) for i in range(len(sc.names))]
    rel_s, rels, cpu0 = 0.0, 0, time.process_time()
    with _Timer() as tm, np.errstate(invalid="ignore"):
        for s in range(sc.steps):
            for r in robots:
                r.feed_own(r.own_messages(s))
            boxes = [r.box() for r in robots]
            for r in robots:
                for b in boxes:
                    r.feed_peer_box(b)
                ms = r.relative_messages(s, [n for n in sc.names if n != r.name])
                t = time.process_time()
                r.cooperate(ms)
                rel_s += time.process_time() - t
                rels += 1
            for r in robots:
                r.record(s)
    cpu = time.process_time() - cpu0
    SlidingWindowCP.scalar_path = True
    lo = np.concatenate([np.array(r.tracks["multi_cp"].lo) for r in robots])
    hi = np.concatenate([np.array(r.tracks["multi_cp"].hi) for r in robots])
    truth = np.concatenate([np.array(r.truth) for r in robots])
    inside = np.all((lo[:, :2] <= truth[:, :2]) & (truth[:, :2] <= hi[:, :2]), axis=1)
    area = float(np.sum((hi[:, 0] - lo[:, 0]) * (hi[:, 1] - lo[:, 1])) * sc.dt)
    return {
        "relative_us": rel_s / rels * 1e6,
        "window_solve_us": tm.solve_s / max(tm.solves, 1) * 1e6,
        "step_us": cpu / (sc.steps * len(robots)) * 1e6,
        "containment": float(inside.mean()),
        "area": area,
        "lo": lo,
        "hi": hi,
    }


def daemon(duration_s: float, seed: int, scalar: bool) -> dict:
    """The daemon's CP service on robot 0 of the scenario, GPS at 1 Hz."""
    sc = simulate(paper_robots(1), duration_s=duration_s, seed=seed, gps_every=10)
    t0 = sc.truth[0, 0]
    data = config_data(load_config(None))
    data["initial_pose"] = [float(t0[0]), float(t0[1]), math.degrees(float(t0[2]))]
    data["geometry"]["wheel_base_m"] = sc.wheelbase_m
    svc = LocalizationAdapter(parse_config(data))
    svc.cp.scalar_path = scalar
    dev = PaperDevices(sc, 0)
    msgs = [(s, m) for s in range(sc.steps) for m in dev.messages(s)]
    boxes, inside = [], []
    with _Timer() as tm, np.errstate(invalid="ignore"):
        cpu0 = time.process_time()
        for s, (topic, m) in msgs:
            for _, b in svc.feed(topic, m):
                t = sc.truth[0, s]
                inside.append(b.x.lo <= t[0] <= b.x.hi and b.y.lo <= t[1] <= b.y.hi)
                boxes.append((b.x.lo, b.x.hi, b.y.lo, b.y.hi, b.theta.lo, b.theta.hi))
        cpu = time.process_time() - cpu0
    return {
        "step_us": cpu / sc.steps * 1e6,
        "window_solve_us": tm.solve_s / max(tm.solves, 1) * 1e6,
        "containment": float(np.mean(inside)),
        "boxes": np.array(boxes),
    }


def _wider(new_lo, new_hi, old_lo, old_hi) -> float:
    """The most any bound of the new boxes lies outside the old ones (<= 0: inside)."""
    return float(max(np.max(old_lo - new_lo), np.max(new_hi - old_hi)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0)
    ap.add_argument("--window", type=int, default=40)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--n", type=int, default=300)
    args = ap.parse_args()
    load0 = os.getloadavg()[0]
    c_old, c_new = contraction_us(args.n, args.seed)
    sc = simulate(duration_s=args.duration, seed=args.seed, errors="uniform")
    old = scenario(sc, args.window, scalar=False)
    new = scenario(sc, args.window, scalar=True)
    diff = float(max(np.max(np.abs(old["lo"] - new["lo"])), np.max(np.abs(old["hi"] - new["hi"]))))
    wider = _wider(new["lo"], new["hi"], old["lo"], old["hi"])
    d_old = daemon(args.duration, args.seed, scalar=False)
    d_new = daemon(args.duration, args.seed, scalar=True)
    bo, bn = d_old["boxes"], d_new["boxes"]
    d_diff = float(np.max(np.abs(bo - bn)))
    d_wider = _wider(bn[:, 0::2], bn[:, 1::2], bo[:, 0::2], bo[:, 1::2])
    load1 = os.getloadavg()[0]
    rows = [
        ("contraction (1 box, 1 peer)", c_old, c_new),
        ("feed_relatives (2 peers)", old["relative_us"], new["relative_us"]),
        ("window solve", old["window_solve_us"], new["window_solve_us"]),
        ("robot-step, whole loop", old["step_us"], new["step_us"]),
        ("daemon: window solve", d_old["window_solve_us"], d_new["window_solve_us"]),
        ("daemon: CP service per step", d_old["step_us"], d_new["step_us"]),
    ]
    print(f"{'CPU µs per call':30s} {'array':>10s} {'scalar':>10s} {'ratio':>7s}")
    for name, a, b in rows:
        print(f"{name:30s} {a:10.1f} {b:10.1f} {a / b:7.1f}")
    print(
        f"multi-CP containment array/scalar {old['containment']:.4f}/{new['containment']:.4f}, "
        f"area {old['area']:.4f}/{new['area']:.4f} m2 s, largest bound difference {diff:.3g} m, "
        f"scalar wider by at most {wider:.3g}"
    )
    print(
        f"daemon containment array/scalar {d_old['containment']:.4f}/{d_new['containment']:.4f}, "
        f"largest bound difference {d_diff:.3g}, scalar wider by at most {d_wider:.3g}"
    )
    print(f"load average {load0:.2f} -> {load1:.2f}")
    out = {
        "contraction_us_old": round(c_old, 1),
        "contraction_us_new": round(c_new, 1),
        "relative_us_old": round(old["relative_us"], 1),
        "relative_us_new": round(new["relative_us"], 1),
        "window_solve_us_old": round(old["window_solve_us"], 1),
        "window_solve_us_new": round(new["window_solve_us"], 1),
        "step_us_old": round(old["step_us"], 1),
        "step_us_new": round(new["step_us"], 1),
        "containment_old": old["containment"],
        "containment_new": new["containment"],
        "area_old": round(old["area"], 6),
        "area_new": round(new["area"], 6),
        "max_bound_diff_m": diff,
        "scalar_wider_m": wider,
        "daemon_window_solve_us_old": round(d_old["window_solve_us"], 1),
        "daemon_window_solve_us_new": round(d_new["window_solve_us"], 1),
        "daemon_step_us_old": round(d_old["step_us"], 1),
        "daemon_step_us_new": round(d_new["step_us"], 1),
        "daemon_containment_old": d_old["containment"],
        "daemon_containment_new": d_new["containment"],
        "daemon_max_bound_diff": d_diff,
        "daemon_scalar_wider": d_wider,
        "load": [round(load0, 2), round(load1, 2)],
        "source": "simulator (fakes.world.paper_scenario, uniform errors)",
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
