"""PNG plots of an analysis (matplotlib, Agg backend): path, map, errors over time, boxes."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.colors import to_rgb
from matplotlib.patches import Rectangle

from hilnav.analysis.geometry import apply_fit
from hilnav.analysis.maps import grid_of_msg, load_plan
from hilnav.analysis.result import Analysis, RobotAnalysis
from hilnav.analysis.tracks import NS

COLORS = {
    "truth": "black",
    "pose": "tab:blue",
    "heading": "tab:orange",
    "odometry": "tab:red",
    "gyro": "tab:purple",
    "gps": "tab:green",
}
# PNGs carry no creation time, so the same analysis gives the same files.
_PNG_META = {"Software": None}


def _color(name: str) -> str:
    return COLORS.get(name, "tab:gray")


def _plan_walls(ax, plan_name: str | None) -> None:
    if not plan_name:
        return
    try:
        plan = load_plan(plan_name)
    except ValueError:
        return
    for x0, y0, x1, y1 in plan.segments:
        ax.plot([x0, x1], [y0, y1], color="0.35", lw=1.5, zorder=1)


def _save(fig, path: Path) -> Path:
    fig.tight_layout()
    fig.savefig(path, dpi=110, metadata=_PNG_META)
    plt.close(fig)
    return path


# At most this many CP boxes are drawn on the path plot, evenly spaced in time.
PATH_BOXES = 6


def _gps_points(ax, ra: RobotAnalysis) -> None:
    """The GPS fixes: kept ones as dots, those the outlier rule excluded as crosses."""
    _, gx, gy, _ = ra.series.log.gps.arrays()
    keep = ra.series.gps_keep
    if keep is None:
        keep = np.ones(len(gx), dtype=bool)
    ax.scatter(gx[keep], gy[keep], s=6, color=_color("gps"), label="GPS", zorder=2)
    if (~keep).any():
        ax.scatter(gx[~keep], gy[~keep], s=14, marker="x", lw=0.8, color="tab:brown",
                   label="GPS outliers (excluded)", zorder=2)  # fmt: skip


def _sparse_boxes(ax, ra: RobotAnalysis) -> None:
    """A few CP boxes (evenly spaced in time, the last included), lightly filled, below
    the paths, so that they show the box size without hiding the paths."""
    boxes = [
        b
        for b in ra.series.boxes.boxes
        if not (b.x.empty or b.y.empty) and np.isfinite([b.x.lo, b.x.hi, b.y.lo, b.y.hi]).all()
    ]
    if not boxes:
        return
    picks = sorted({round(i) for i in np.linspace(0, len(boxes) - 1, min(PATH_BOXES, len(boxes)))})
    for n, i in enumerate(picks):
        b = boxes[i]
        ax.add_patch(
            Rectangle((b.x.lo, b.y.lo), b.x.width, b.y.width, fc=(*to_rgb("tab:cyan"), 0.06),
                      ec="tab:cyan", lw=0.8, ls="--", zorder=1.5,
                      label=f"CP boxes ({len(picks)} of {len(boxes)})" if n == 0 else None)
        )  # fmt: skip


def plot_path(ra: RobotAnalysis, plan_name: str | None, path: Path) -> Path | None:
    rl, errors, boxes = ra.series.log, ra.series.errors, ra.series.boxes
    if not rl.sources and len(rl.truth) == 0 and len(rl.gps) == 0:
        return None
    fig, ax = plt.subplots(figsize=(7, 6))
    _plan_walls(ax, plan_name)
    if len(rl.gps):
        _gps_points(ax, ra)
    if len(rl.truth):  # wide and pale, under the estimates that follow it closely
        _, tx, ty, _ = rl.truth.arrays()
        ax.plot(tx, ty, color="0.7", lw=3.5, label="truth", zorder=2.5, solid_capstyle="round")
    fitted = ra.reference == "gps"  # other frames: draw each track after its rigid fit
    for name, tr in sorted(rl.sources.items()):
        if name == "gyro" or len(tr) == 0:
            continue
        label = name
        if name in errors:  # the (start-aligned) track, as the errors were computed
            x, y = errors[name].est_x, errors[name].est_y
            if fitted:
                x, y = apply_fit(errors[name].fit, x, y)
                label += " (rigid fit)"
        else:
            _, x, y, _ = tr.arrays()
        ax.plot(x, y, color=_color(name), lw=0.9, label=label, zorder=3)
    if rl.landmarks is not None and len(rl.landmarks.xs):
        lx, ly = np.asarray(rl.landmarks.xs, float), np.asarray(rl.landmarks.ys, float)
        if fitted and "pose" in errors:
            lx, ly = apply_fit(errors["pose"].fit, lx, ly)
        ax.scatter(lx, ly, marker="+", s=25, color="tab:olive", label="landmarks", zorder=5)
    if boxes is not None:
        _sparse_boxes(ax, ra)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{ra.name}: paths (reference: {ra.reference})")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def plot_map(ra: RobotAnalysis, plan_name: str | None, path: Path) -> Path | None:
    msg = ra.series.log.last_map
    if msg is None:
        return None
    grid = grid_of_msg(msg)
    p = grid.probability()
    img = np.where(grid.logodds == 0, 0.5, 1.0 - p)
    x0, y0 = grid.origin
    rows, cols = grid.shape
    extent = (x0, x0 + cols * grid.resolution, y0, y0 + rows * grid.resolution)
    fig, ax = plt.subplots(figsize=(7, 6))
    ax.imshow(img, origin="lower", extent=extent, cmap="gray", vmin=0.0, vmax=1.0, zorder=0)
    _plan_walls(ax, plan_name)
    if len(ra.series.log.truth):
        _, tx, ty, _ = ra.series.log.truth.arrays()
        ax.plot(tx, ty, color="tab:red", lw=1.0, label="truth path")
        ax.legend(loc="best", fontsize=8)
    ratio = ra.map.match_ratio if ra.map is not None else None
    title = f"{ra.name}: occupancy grid"
    if ratio is not None:
        title += f" (match ratio {100 * ratio:.1f} % vs {plan_name})"
    ax.set_title(title)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    return _save(fig, path)


def plot_errors(ra: RobotAnalysis, path: Path) -> Path | None:
    if not ra.series.errors:
        return None
    has_head = any(np.isfinite(e.head_err).any() for e in ra.series.errors.values())
    n = 2 if has_head else 1
    fig, axes = plt.subplots(n, 1, figsize=(8, 3.2 * n), sharex=True, squeeze=False)
    t0 = min(int(e.t[0]) for e in ra.series.errors.values())
    fitted = ra.reference == "gps"  # as the path plot draws them: after the rigid fit
    for name, e in sorted(ra.series.errors.items()):
        ts = (e.t - t0) / NS
        pos = e.pos_err_fit if fitted else e.pos_err
        if np.isfinite(pos).any():
            axes[0, 0].plot(ts, pos, color=_color(name), lw=1.0, label=name)
        if has_head and np.isfinite(e.head_err).any():
            axes[1, 0].plot(ts, np.degrees(e.head_err), color=_color(name), lw=1.0, label=name)
    axes[0, 0].set_ylabel("position error (m)")
    title = f"{ra.name}: errors against {ra.reference}"
    if fitted:
        fx = ra.gps_fixes
        title += " after the rigid fit"
        if fx is not None and fx.excluded:
            title += f" ({fx.excluded} of {fx.fixes} fixes excluded as outliers)"
    axes[0, 0].set_title(title)
    axes[0, 0].legend(loc="best", fontsize=8)
    axes[0, 0].grid(alpha=0.3)
    if has_head:
        axes[1, 0].set_ylabel("heading error (deg)")
        axes[1, 0].legend(loc="best", fontsize=8)
        axes[1, 0].grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time (s)")
    return _save(fig, path)


def plot_boxes(ra: RobotAnalysis, path: Path) -> Path | None:
    bs = ra.series.boxes
    if bs is None:
        return None
    fig, ax = plt.subplots(figsize=(8, 3.5))
    ts = (bs.t - bs.t[0]) / NS
    ax.plot(ts, bs.area, color="tab:blue", lw=1.0, label="box area")
    bad = bs.contained == 0
    if bad.any():
        ax.scatter(ts[bad], bs.area[bad], color="tab:red", s=12, label="truth outside", zorder=3)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("area (m²)")
    ax.ticklabel_format(axis="y", useOffset=False)
    finite = bs.area[np.isfinite(bs.area)]  # an unbounded box (nothing known yet) is off the plot
    top = float(np.max(finite)) * 1.1 if finite.size else 1.0
    ax.set_ylim(bottom=0.0, top=max(top, 1e-3))
    box = ra.cp_boxes.containment if ra.cp_boxes is not None else None
    frac = box.contained_fraction if box is not None else None
    title = f"{ra.name}: CP pose box areas"
    if frac is not None:
        title += f" (truth inside {100 * frac:.1f} %)"
    ax.set_title(title)
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def write_plots(analysis: Analysis, out_dir: Path) -> list[Path]:
    """All plots that the log allows, one set per robot; returns the files written."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files: list[Path] = []
    for name, ra in analysis.robots.items():
        for fn, kind in (
            (lambda p, ra=ra: plot_path(ra, analysis.plan_name, p), "path"),
            (lambda p, ra=ra: plot_map(ra, analysis.plan_name, p), "map"),
            (lambda p, ra=ra: plot_errors(ra, p), "error"),
            (lambda p, ra=ra: plot_boxes(ra, p), "boxes"),
        ):
            f = fn(out_dir / f"{name}_{kind}.png")
            if f is not None:
                files.append(f)
    return files
