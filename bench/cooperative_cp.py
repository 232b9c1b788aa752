"""Benchmark: the multi-robot experiment of ekf-vs-cp.txt §2.4, EKF versus single and
multiple (cooperative) constraint propagation, under several error models.

Three robots (robot 1: right 0.98 m/s, left 1.0 m/s; robot 2: straight at 1 m/s;
robot 3: right 1.0, left 0.99 m/s) drive 50 s with wheel encoders, a heading gyro and a
GPS (fakes.world.paper_scenario); for the cooperative case each robot also measures
range and bearing to the others. Per robot: an EKF (its 3-sigma box, as in the paper),
single CP (own sensors) and multiple CP (plus the peers' latest boxes and the relative
measurements), CP over a sliding window of past states.

``--errors`` chooses how every sensor's error is drawn against the bound the localizers
assume (fakes.world.error_models): ``uniform`` inside the bound (the paper's assumption;
the default), ``gaussian`` (sigma = bound / sqrt 3), ``bias`` (0.5 bound stuck on one
side plus uniform), ``heavy`` (Student-t, nu = 3, the uniform's median); ``all`` runs each
with the same seed and truth. ``--outliers`` is CP's q (GPS fixes per window it may vote
out).

Figures (PNG in --out, default bench/out/, for the uniform model): the cumulative box
area over time (paper fig. 3) and the position error with the bounds of each method over
time (fig. 4). A table per model, and the LAST line is a JSON object: ``models`` holds,
per error model, for each method m in ekf, single_cp, multi_cp:

- ``m_containment`` (fraction of robot-steps whose box holds the truth in x, y, theta;
  an empty box holds nothing), ``m_area`` (cumulative area, m^2 s, summed over robots),
  ``m_area_median_m2`` (median over non-empty boxes), ``m_late_mean_area_m2``;
- CP only, how it fails: ``m_empty`` (robot-steps with an empty box: the inconsistency
  is seen), ``m_silent_wrong`` (robot-steps with the truth outside a non-empty box),
  ``m_first_loss_s``, ``m_named_outliers`` (entries of the localizers' ``dropped_*`` /
  ``*outlier*`` lists), ``m_inconsistency_flags`` (their ``skipped`` "inconsistent..."
  counts);

and ``ekf_rmse_m``, ``integrity_alarms`` (EKF estimate outside the multiple-CP box),
``false_alarms`` (of those, while the EKF's 3-sigma box held the truth),
``missed_alarms`` (EKF box missed the truth, no alarm), ``gps_dropped``,
``errors_outside_bound`` (fraction of the drawn gyro, GPS, range and bearing errors
beyond their bounds), ``steps_per_second`` / ``cpu_steps_per_second``, and the
recursive CP baseline (window 1) unless ``--no-baseline``. With one model, its figures
are also at the top level (the keys of earlier versions).

    python bench/cooperative_cp.py [--errors uniform|gaussian|bias|heavy|all] [--seed N]
        [--window 40] [--outliers 0] [--gps-every 1] [--out DIR] [--no-baseline]
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

from fakes.world.error_models import ERROR_MODELS
from fakes.world.paper_scenario import PAPER_ROBOTS, simulate
from hilnav.fleet.paper import METHODS, PaperRobot
from numerics.angles import wrap_angles


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


def _arrays(r: PaperRobot, m: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A method's per-step (lo, hi) bounds and containment flags of one robot."""
    tr = r.tracks[m]
    return np.array(tr.lo), np.array(tr.hi), np.array(tr.contained, dtype=bool)


def _named(cp: object) -> tuple[int, int]:
    """(measurements a CP localizer named as outliers, inconsistencies it flagged): every
    list attribute named ``dropped_*`` or ``*outlier*``, and the ``skipped`` counts whose
    reason starts with "inconsistent"."""
    named = sum(
        len(v)
        for k, v in vars(cp).items()
        if ("dropped" in k or "outlier" in k) and isinstance(v, list | tuple | set | dict)
    )
    skipped = getattr(cp, "skipped", {}) or {}
    flags = sum(n for k, n in skipped.items() if str(k).startswith("inconsistent"))
    return named, flags


def _outside_bound(sc) -> float:
    """Fraction of the gyro, GPS, range and bearing errors drawn outside their bounds."""
    b, n = sc.bounds, len(sc.names)
    gyro = np.abs(sc.gyro - sc.truth[:, :, 2]) > b.gyro_rad
    fix = ~np.isnan(sc.gps[:, :, 0])
    gps = (np.abs(sc.gps - sc.truth[:, :, :2]) > b.gps_m)[fix]
    rng_err, brg_err = [], []
    for i in range(n):
        for j in range(n):
            if i != j:
                d = sc.truth[j, :, :2] - sc.truth[i, :, :2]
                rng_err.append(np.abs(sc.rel_range[i, j] - np.hypot(d[:, 0], d[:, 1])))
                brg = np.arctan2(d[:, 1], d[:, 0]) - sc.truth[i, :, 2]
                brg_err.append(np.abs(wrap_angles(sc.rel_bearing[i, j] - brg)))
    flags = [gyro.ravel(), gps.ravel()]
    if rng_err:
        flags += [np.concatenate(rng_err) > b.range_m, np.concatenate(brg_err) > b.bearing_rad]
    return float(np.mean(np.concatenate(flags)))


def figures_of(robots: list[PaperRobot], sc) -> dict[str, float | int | None]:
    """Every figure of one run (see docs/benchmarks.md for the definitions)."""
    dt = sc.dt
    out: dict[str, float | int | None] = {}
    for m in METHODS:
        lo_hi_c = [_arrays(r, m) for r in robots]
        empty = np.concatenate([~np.all(lo <= hi, axis=1) for lo, hi, _ in lo_hi_c])
        inside = np.concatenate([c for _, _, c in lo_hi_c])
        area = np.concatenate(
            [(hi[:, 0] - lo[:, 0]) * (hi[:, 1] - lo[:, 1]) for lo, hi, _ in lo_hi_c]
        )
        area = np.where(empty, 0.0, area)
        late = np.concatenate([a[len(a) // 2 :] for a in np.split(area, len(robots))])
        out[f"{m}_containment"] = round(float(inside.mean()), 4)
        out[f"{m}_area"] = round(float(area.sum() * dt), 4)
        out[f"{m}_area_median_m2"] = (
            round(float(np.median(area[~empty])), 5) if (~empty).any() else None
        )
        out[f"{m}_late_mean_area_m2"] = round(float(late.mean()), 5)
        if m != "ekf":
            lost = [np.flatnonzero(~c) for _, _, c in lo_hi_c]
            first = min((int(ix[0]) for ix in lost if len(ix)), default=None)
            cps = [r.single if m == "single_cp" else r.multi for r in robots]
            named = [_named(cp) for cp in cps]
            out[f"{m}_empty"] = int(empty.sum())
            out[f"{m}_silent_wrong"] = int((~inside & ~empty).sum())
            out[f"{m}_first_loss_s"] = None if first is None else round(first * dt, 2)
            out[f"{m}_named_outliers"] = sum(n for n, _ in named)
            out[f"{m}_inconsistency_flags"] = sum(f for _, f in named)
    if out["ekf_area"]:
        out["multi_over_ekf_area"] = round(float(out["multi_cp_area"]) / float(out["ekf_area"]), 4)
    err = np.concatenate(
        [np.hypot(*(0.5 * (lo + hi)[:, :2] - np.array(r.truth)[:, :2]).T) for r in robots
         for lo, hi, _ in [_arrays(r, "ekf")]]
    )  # fmt: skip
    out["ekf_rmse_m"] = round(float(np.sqrt(np.mean(err**2))), 4)
    step = {int(t): s for s, t in enumerate(sc.stamps_ns)}
    alarms = false = missed = 0
    for r in robots:
        _, _, ekf_ok = _arrays(r, "ekf")
        raised = np.zeros(len(ekf_ok), dtype=bool)
        raised[[step[t] for t in r.monitor.alarms if t in step]] = True
        alarms += int(raised.sum())
        false += int((raised & ekf_ok).sum())
        missed += int((~raised & ~ekf_ok).sum())
    out["integrity_alarms"] = alarms
    out["false_alarms"] = false
    out["missed_alarms"] = missed
    out["gps_dropped"] = sum(len(r.multi.dropped_gps) for r in robots)
    out["errors_outside_bound"] = round(_outside_bound(sc), 4)
    return out


def run_model(args: argparse.Namespace, errors: str) -> tuple[dict, list[PaperRobot], object]:
    sc = simulate(
        PAPER_ROBOTS,
        duration_s=args.duration,
        seed=args.seed,
        gps_every=args.gps_every,
        errors=errors,
    )
    with np.errstate(invalid="ignore"):  # empty boxes are (inf, -inf): scored, not warned
        robots, secs, cpu = run(sc, args.window, outliers=args.outliers)
    res = figures_of(robots, sc)
    res["steps_per_second"] = round(sc.steps * len(robots) / secs, 1)
    res["cpu_steps_per_second"] = round(sc.steps * len(robots) / max(cpu, 1e-9), 1)
    if not args.no_baseline:
        with np.errstate(invalid="ignore"):
            b = figures_of(run(sc, 1, outliers=args.outliers)[0], sc)
        res["recursive_single_cp_area"] = b["single_cp_area"]
        res["recursive_multi_cp_area"] = b["multi_cp_area"]
        res["recursive_multi_cp_containment"] = b["multi_cp_containment"]
    return res, robots, sc


def table(models: dict[str, dict]) -> list[str]:
    head = (
        f"{'errors':9s} {'outside':>7s} | {'CP contained single/multi':>25s} | "
        f"{'empty':>9s} {'wrong':>9s} {'named':>7s} | {'median area s/m/EKF m2':>22s} | "
        f"{'EKF in':>6s} {'RMSE m':>6s} | {'alarms/false':>12s}"
    )
    rows = [head, "-" * len(head)]
    for name, f in models.items():
        area = "/".join(
            "-" if f[f"{m}_area_median_m2"] is None else f"{f[f'{m}_area_median_m2']:.3f}"
            for m in ("single_cp", "multi_cp", "ekf")
        )
        rows.append(
            f"{name:9s} {f['errors_outside_bound']:7.3f} | "
            f"{f['single_cp_containment']:12.4f} /{f['multi_cp_containment']:11.4f} | "
            f"{f['single_cp_empty']:4d}/{f['multi_cp_empty']:<4d} "
            f"{f['single_cp_silent_wrong']:4d}/{f['multi_cp_silent_wrong']:<4d} "
            f"{f['multi_cp_named_outliers']:7d} | {area:>22s} | "
            f"{f['ekf_containment']:6.3f} {f['ekf_rmse_m']:6.3f} | "
            f"{f['integrity_alarms']:5d}/{f['false_alarms']:<6d}"
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--window", type=int, default=40)
    ap.add_argument(
        "--gps-every", type=int, default=1, help="GPS fix every N odometry steps (0.1 s)"
    )
    ap.add_argument("--duration", type=float, default=50.0)
    ap.add_argument(
        "--errors",
        default="uniform",
        choices=(*ERROR_MODELS, "all"),
        help="error model of every sensor against its bound (fakes.world.error_models); "
        "all: each in turn, same seed and truth",
    )
    ap.add_argument(
        "--outliers", type=int, default=0, help="q: measurements per window CP may vote out"
    )
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parent / "out")
    ap.add_argument("--no-baseline", action="store_true", help="skip the recursive CP baseline")
    args = ap.parse_args(argv)

    names = list(ERROR_MODELS) if args.errors == "all" else [args.errors]
    models: dict[str, dict] = {}
    for name in names:
        res, robots, sc = run_model(args, name)
        models[name] = res
        if name == "uniform":
            for p in figures(robots, sc.dt, args.out):
                print(f"wrote {p}")
    for row in table(models):
        print(row)
    out: dict = {}
    if len(names) == 1:
        out.update(models[names[0]])  # one model: its figures at the top level too
    out.update(
        {
            "errors": args.errors,
            "window": args.window,
            "seed": args.seed,
            "gps_every": args.gps_every,
            "outliers": args.outliers,
            "models": models,
        }
    )
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
