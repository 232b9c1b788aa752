"""One error against GPS for ``hilnav analyze`` and the Victoria Park bench: the outlier rule,
the latest pose at each kept fix, the rigid fit; the plots show what the figures say."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hilnav.analysis.analyze import analyze
from hilnav.analysis.gps_error import (
    errors_at_fixes,
    gps_inliers,
    travelled_from_speed,
)
from hilnav.analysis.report import digest
from hilnav.log.writer import LogWriter
from msgs import GpsFix, Pose2D, PoseEstimate, VehicleControl

T0 = 5_000_000_000
RATE_HZ = 40
SPEED = 3.0
OUTLIERS = (30, 31, 90)  # fix indices thrown 40 m off


def _car() -> dict[str, np.ndarray]:
    """A car on a circle at 3 m/s for 200 s: controls at 40 Hz, GPS at 1 Hz with noise and
    three jumps, and a path in a frame of its own (rotated by 40 deg, shifted)."""
    rng = np.random.default_rng(7)
    t = np.arange(200 * RATE_HZ) / RATE_HZ
    ang = SPEED * t / 60.0  # radius 60 m
    x, y = 60.0 * np.sin(ang), 60.0 * (1.0 - np.cos(ang))
    fix = np.arange(0, len(t), RATE_HZ)
    gx = x[fix] + rng.normal(0, 0.3, len(fix))
    gy = y[fix] + rng.normal(0, 0.3, len(fix))
    gx[list(OUTLIERS)] += 40.0
    c, s = math.cos(math.radians(40)), math.sin(math.radians(40))
    return {"t": t, "x": c * x - s * y + 7.0, "y": s * x + c * y - 3.0, "th": ang,
            "gt": t[fix], "gx": gx, "gy": gy}  # fmt: skip


def _write(path: Path, car: dict[str, np.ndarray]) -> None:
    fixes = dict(zip(np.round(car["gt"] * RATE_HZ).astype(int), range(len(car["gt"])), strict=True))
    with LogWriter(path, metadata={"robot": "vp"}, wall_clock=False) as w:
        for i, ts in enumerate(car["t"]):
            t = T0 + int(round(ts * 1e9))
            w.write("/vp/control", VehicleControl(t, SPEED, 0.0), t)
            if i in fixes:
                k = fixes[i]
                w.write("/vp/gps", GpsFix(t, mode=2, east_m=car["gx"][k], north_m=car["gy"][k]), t)
            p = Pose2D(car["x"][i], car["y"][i], car["th"][i])
            w.write("/vp/pose", PoseEstimate(t, p, (0.0,) * 9), t)


def test_outlier_rule_and_error_at_fixes() -> None:
    car = _car()
    travel = travelled_from_speed(car["t"], np.full(len(car["t"]), SPEED))
    assert travel[-1] == pytest.approx(SPEED * car["t"][-1])
    keep = gps_inliers(car["gt"], car["gx"], car["gy"], car["t"], travel)
    assert sorted(np.flatnonzero(~keep).tolist()) == list(OUTLIERS)
    ge = errors_at_fixes(car["t"], car["x"], car["y"], car["gt"], car["gx"], car["gy"], keep)
    assert ge is not None and len(ge.used) == len(car["gt"]) - len(OUTLIERS)
    assert ge.fit[2] == pytest.approx(math.radians(-40), abs=0.01)
    assert ge.error.min() > 3.0 and 0.2 < ge.ate_rmse_m < 0.6  # the fixes' noise, 0.3 m/axis
    # The estimate at a fix is the latest pose at or before it (fix times are pose times).
    assert np.array_equal(ge.est_x, car["x"][np.round(car["gt"][ge.used] * RATE_HZ).astype(int)])
    with_outliers = errors_at_fixes(car["t"], car["x"], car["y"], car["gt"], car["gx"], car["gy"])
    assert with_outliers is not None and with_outliers.ate_rmse_m > 3 * ge.ate_rmse_m


def test_analyze_uses_the_same_definition(tmp_path: Path) -> None:
    car = _car()
    path = tmp_path / "car.mcap"
    _write(path, car)
    analysis = analyze(path)
    ra = analysis.robots["vp"]
    assert ra.reference == "gps" and ra.gps_fixes is not None
    assert (ra.gps_fixes.fixes, ra.gps_fixes.excluded) == (len(car["gt"]), len(OUTLIERS))
    assert ra.gps_fixes.travelled_from == "controls"
    travel = travelled_from_speed(car["t"], np.full(len(car["t"]), SPEED))
    keep = gps_inliers(car["gt"], car["gx"], car["gy"], car["t"], travel)
    ge = errors_at_fixes(car["t"], car["x"], car["y"], car["gt"], car["gx"], car["gy"], keep)
    fitted = ra.paths["pose"].position.after_rigid_fit_m
    assert fitted.rms == pytest.approx(ge.ate_rmse_m, rel=1e-6)
    assert fitted.max == pytest.approx(float(ge.error_fit.max()), rel=1e-6)
    # The error series the plot draws is the fitted one, like the path plot's tracks.
    e = ra.series.errors["pose"]
    assert np.allclose(e.pos_err_fit, ge.error_fit) and len(e.t) == len(ge.used)
    assert any("after the rigid fit: RMS" in line for line in digest(analysis))
