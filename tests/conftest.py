"""Shared test helpers: run the ``hilnav`` CLI of *this* checkout in a subprocess."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _find_shared() -> Path:
    """``../shared`` beside the checkout (CI), or the nearest ancestor's ``shared``."""
    env = os.environ.get("HILNAV_SHARED")
    if env:
        return Path(env)
    for parent in ROOT.parents:
        if (parent / "shared" / "DESIGN.md").is_file():
            return parent / "shared"
    return ROOT.parent / "shared"


SHARED = _find_shared()
HILNAV = [sys.executable, "-m", "hilnav"]


def hilnav_env(**extra: str) -> dict[str, str]:
    """Environment for subprocesses: this checkout first on PYTHONPATH, unbuffered output."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env["PYTHONUNBUFFERED"] = "1"
    env.update(extra)
    return env


@pytest.fixture
def shared_dir() -> Path:
    """The project's shared folder (papers, protocols, data); skips if absent."""
    if not SHARED.is_dir():
        pytest.skip(f"shared folder not found at {SHARED}")
    return SHARED


def require(path: Path) -> Path:
    """``path`` (a part of the shared folder's data); the test, or every test of the
    fixture, that asks for it is skipped, with the path, when it is absent."""
    if not path.exists():
        pytest.skip(f"shared data not found at {path}")
    return path


def pump(driver, seconds: float, v: float | None = None, w: float = 0.0):
    """Read a driver for ``seconds`` (driving at v, w if given); the last odometry seen."""
    from msgs import RobotOdometry

    last = None
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if v is not None:
            driver.set_velocity(v, w)
        for m in driver.read(0.05):
            if isinstance(m, RobotOdometry):
                last = m
    return last


_LIBM = ctypes.CDLL(ctypes.util.find_library("m"))
_FE_TONEAREST = 0  # glibc on x86-64 and aarch64


@pytest.fixture(autouse=True)
def _round_to_nearest():
    """Every test starts from IEEE round-to-nearest: Codac (the interval tests' oracle)
    switches the process to upward rounding, which must not leak into other tests."""
    _LIBM.fesetround(_FE_TONEAREST)
    yield
    _LIBM.fesetround(_FE_TONEAREST)
