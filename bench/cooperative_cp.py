"""Benchmark: the multi-robot experiment of ekf-vs-cp.txt §2.4, EKF versus single and
multiple (cooperative) constraint propagation.

Three robots (robot 1: right 0.98 m/s, left 1.0 m/s; robot 2: straight at 1 m/s;
robot 3: right 1.0, left 0.99 m/s) drive 50 s with wheel encoders, a heading gyro and a
GPS, every error uniform inside a bound (fakes.world.paper_scenario); for the cooperative
case each robot also measures range and bearing to the others. Per robot: an EKF (its
3-sigma box, as in the paper), single CP (own sensors) and multiple CP (plus the peers'
latest boxes and the relative measurements), CP over a sliding window of past states.

Figures (PNG in --out, default bench/out/): the cumulative box area over time (paper
fig. 3) and the position error with the bounds of each method over time (fig. 4).
The LAST line is a JSON object: ekf_area, single_cp_area, multi_cp_area (cumulative box
area summed over the robots, m^2 s), ekf_containment, single_cp_containment,
multi_cp_containment (fraction of robot-steps whose box holds the truth in x, y and
theta), steps_per_second (robot-steps of all three localizers per wall second;
cpu_steps_per_second per CPU second, which a busy machine distorts less), the
recursive CP baseline (window 1), late mean areas and the integrity alarms.

    python bench/cooperative_cp.py [--seed N] [--window 40] [--gps-every 1] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from fakes.world.paper_scenario import PAPER_ROBOTS, simulate
from hilnav.fleet.paper import METHODS, PaperRobot, summary


def run(sc, window: int, outliers: int = 0) -> tuple[list[PaperRobot], float, float]:
    robots = [PaperRobot(sc, i, window=window, outliers=outliers) for i in range(len(sc.names))]
    t0, c0 = time.perf_counter(), time.process_time()
    for s in range(sc.steps):
        for r in robots:
            r.feed_own(r.own_messages(s))
        boxes = [r.box() for r in robots]  # every robot publishes its box ...
        for r in robots:
            for b in boxes:
                r.feed_peer_box(b)  # ... and the others receive it
            r.cooperate(r.relative_messages(s, [n for n in sc.names if n != r.name]))
        for r in robots:
            r.record(s)
    return robots, time.perf_counter() - t0, time.process_time() - c0


def figures(robots: list[PaperRobot], dt: float, out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out.mkdir(parents=True, exist_ok=True)
    colors = {"ekf": "tab:red", "single_cp": "tab:blue", "multi_cp": "tab:green"}
    labels = {"ekf": "EKF (3 sigma)", "single_cp": "single CP", "multi_cp": "multiple CP"}
    n = len(robots[0].tracks["ekf"].area_m2)
    t = np.arange(n) * dt
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for m in METHODS:
        a = np.sum([np.asarray(r.tracks[m].area_m2) for r in robots], axis=0)
        ax.plot(t, np.cumsum(a) * dt, color=colors[m], label=labels[m])
    ax.set_xlabel("time [s]")
    ax.set_ylabel("cumulative box area, all robots [m$^2$ s]")
    ax.set_title("EKF vs CP: cumulative area of the position boxes (paper fig. 3)")
    ax.grid(alpha=0.3)
    ax.legend()
    p1 = out / "cooperative_cp_area.png"
    fig.tight_layout()
    fig.savefig(p1, dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(len(robots), 2, figsize=(11, 2.6 * len(robots)), sharex=True)
    axes = np.atleast_2d(axes)
    for ri, r in enumerate(robots):
        truth = np.array(r.truth)
        for c, lab in enumerate(("x", "y")):
            ax = axes[ri, c]
            for m in METHODS:
                lo = np.array(r.tracks[m].lo)[:, c] - truth[:, c]
                hi = np.array(r.tracks[m].hi)[:, c] - truth[:, c]
                ax.plot(
                    t, lo, color=colors[m], lw=0.8, label=labels[m] if (ri, c) == (0, 0) else None
                )
                ax.plot(t, hi, color=colors[m], lw=0.8)
            ekf_mid = 0.5 * (
                np.array(r.tracks["ekf"].lo)[:, c] + np.array(r.tracks["ekf"].hi)[:, c]
            )
            ax.plot(
                t,
                ekf_mid - truth[:, c],
                color="k",
                lw=0.6,
                label="EKF error" if (ri, c) == (0, 0) else None,
            )
            ax.axhline(0.0, color="grey", lw=0.5)
            ax.set_ylim(-2.5, 2.5)
            ax.set_ylabel(f"{r.name} {lab} bound - truth [m]")
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time [s]")
    axes[0, 0].legend(loc="upper right", fontsize=7)
    fig.suptitle("Bounds around the truth (error 0 must stay inside; paper fig. 4)")
    fig.tight_layout()
    p2 = out / "cooperative_cp_error.png"
    fig.savefig(p2, dpi=110)
    plt.close(fig)
    return [p1, p2]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--window", type=int, default=40)
    ap.add_argument(
        "--gps-every", type=int, default=1, help="GPS fix every N odometry steps (0.1 s)"
    )
    ap.add_argument("--duration", type=float, default=50.0)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "out")
    ap.add_argument("--no-baseline", action="store_true", help="skip the recursive CP baseline")
    args = ap.parse_args(argv)

    sc = simulate(PAPER_ROBOTS, duration_s=args.duration, seed=args.seed, gps_every=args.gps_every)
    robots, secs, cpu = run(sc, args.window)
    res = summary(robots, sc.dt)
    res["steps_per_second"] = round(sc.steps * len(robots) / secs, 1)
    res["cpu_steps_per_second"] = round(sc.steps * len(robots) / max(cpu, 1e-9), 1)
    res["window"] = args.window
    res["seed"] = args.seed
    res["gps_every"] = args.gps_every
    if not args.no_baseline:
        base, _, _ = run(sc, 1)
        b = summary(base, sc.dt)
        res["recursive_single_cp_area"] = b["single_cp_area"]
        res["recursive_multi_cp_area"] = b["multi_cp_area"]
        res["recursive_multi_cp_containment"] = b["multi_cp_containment"]
    for p in figures(robots, sc.dt, args.out):
        print(f"wrote {p}")
    for k in ("ekf", "single_cp", "multi_cp"):
        print(
            f"{k:10s} area {res[k + '_area']:9.3f} m^2 s   containment {res[k + '_containment']:.4f}   late mean area {res[k + '_late_mean_area_m2']:.4f} m^2"
        )
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
