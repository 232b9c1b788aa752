"""numerics: angle wrapping, the eq. (1)-(2) odometry model with every Jacobian checked
against finite differences, and the EKF pieces of eq. (4)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numjac import numeric_jacobian

import msgs
from numerics import ekf
from numerics.angles import wrap, wrap_angle, wrap_angles
from numerics.motion import (
    chord_factor,
    motion,
    motion_jacobians,
    step_to_wheels,
    wheels_jacobian,
    wheels_to_step,
)

ROOT = Path(__file__).resolve().parents[1]
angles = st.floats(-1e6, 1e6, allow_nan=False)


# -- angles ---------------------------------------------------------------------------
def test_msgs_reexports_the_one_scalar_wrap():
    assert msgs.wrap_angle is wrap_angle


def test_import_msgs_does_not_import_numpy():
    code = "import sys, msgs; sys.exit('numpy' in sys.modules)"
    res = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True)
    assert res.returncode == 0, res.stderr.decode()


@pytest.mark.parametrize(
    "a, expect",
    [
        (0.0, 0.0),
        (math.pi, math.pi),
        (-math.pi, math.pi),
        (3 * math.pi, math.pi),
        (7.0, 7.0 - 2 * math.pi),
    ],
)
def test_wrap_edges(a, expect):
    assert wrap_angle(a) == pytest.approx(expect, abs=1e-15)
    assert float(wrap_angles([a])[0]) == pytest.approx(expect, abs=1e-15)


@settings(max_examples=300, deadline=None)
@given(angles)
def test_wrap_range_and_period(a):
    for w in (wrap_angle(a), float(wrap_angles(a))):
        assert -math.pi < w <= math.pi
        k = (a - w) / (2 * math.pi)
        assert abs(k - round(k)) < 1e-9
    # The array form rounds a + pi: it agrees with the exact scalar to about an ulp of it
    # (as angles: on either side of +-pi the two may sit 2 pi apart).
    d = math.remainder(float(wrap_angles(a)) - wrap_angle(a), 2 * math.pi)
    assert abs(d) <= 2 * math.ulp(abs(a) + 2 * math.pi)


def test_wrap_dispatches_on_type():
    assert isinstance(wrap(3.5), float) and wrap(3.5) == wrap_angle(3.5)
    assert isinstance(wrap(np.float64(3.5)), float)
    assert isinstance(wrap(np.array(3.5)), float)
    a = np.array([3 * math.pi, -0.5, 7.0, -math.pi])
    np.testing.assert_array_equal(wrap(a), wrap_angles(a))
    assert wrap(a)[-1] == math.pi


# -- eq. (1)-(2) ----------------------------------------------------------------------
E = 0.33
CASES = [(0.5, False), (1.0, False), (0.0, False), (0.5, True), (1.0, True), (0.3, True)]


def _samples(seed, n=40):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        s = rng.uniform([-10, -10, -4], [10, 10, 4])
        u = rng.uniform([-0.3, -0.4], [0.3, 0.4])
        if rng.random() < 0.3:
            u[1] = rng.uniform(-1e-4, 1e-4)  # the Taylor branch of the chord factor
        yield s, u


@pytest.mark.parametrize("kappa, chord", CASES)
def test_motion_jacobians_match_finite_differences(kappa, chord):
    for s, u in _samples(31):
        f, g = motion_jacobians(s, u, kappa, chord)
        nf = numeric_jacobian(lambda v, u=u: motion(v, u, kappa, chord), s)
        ng = numeric_jacobian(lambda v, s=s: motion(s, v, kappa, chord), u)
        np.testing.assert_allclose(f, nf, atol=1e-6)
        np.testing.assert_allclose(g, ng, atol=1e-6)


def test_wheels_jacobian_matches_finite_differences():
    for dl, dr in np.random.default_rng(32).uniform(-0.2, 0.2, (20, 2)):
        nj = numeric_jacobian(lambda w: wheels_to_step(w[0], w[1], E), [dl, dr])
        np.testing.assert_allclose(wheels_jacobian(E), nj, atol=1e-7)


def test_chord_factor_and_its_derivative():
    for d in [0.0, 1e-6, -1e-5, 1.9e-4, 2.1e-4, 0.01, -0.5, 1.0, 3.0]:
        c, dc = chord_factor(d)
        assert c == pytest.approx(math.sin(d / 2) / (d / 2) if d else 1.0, rel=1e-12)
        h = 1e-6
        num = (chord_factor(d + h)[0] - chord_factor(d - h)[0]) / (2 * h)
        assert dc == pytest.approx(num, abs=1e-7)


def test_step_and_wheels_invert_each_other():
    for dl, dr in np.random.default_rng(33).uniform(-0.2, 0.2, (20, 2)):
        ds, dth = wheels_to_step(dl, dr, E)
        np.testing.assert_allclose(step_to_wheels(ds, dth, E), [dl, dr], atol=1e-15)


def test_midpoint_chord_step_is_the_exact_arc():
    """kappa = 1/2 with the chord factor lands exactly on the constant-curvature arc."""
    x0, y0, th0, ds, dth = 1.0, -2.0, 0.4, 0.8, 0.6
    r = ds / dth
    arc = [x0 + r * (math.sin(th0 + dth) - math.sin(th0)),
           y0 - r * (math.cos(th0 + dth) - math.cos(th0)), th0 + dth]  # fmt: skip
    np.testing.assert_allclose(motion(np.array([x0, y0, th0]), (ds, dth), 0.5, True), arc)


def test_motion_does_not_wrap_theta():
    assert motion(np.array([0.0, 0.0, 3.0]), (0.0, 0.5))[2] == 3.5


# -- eq. (4) --------------------------------------------------------------------------
def test_predict_covariance():
    rng = np.random.default_rng(34)
    p = np.diag([0.1, 0.2, 0.03])
    f, g = motion_jacobians(rng.normal(size=3), (0.2, 0.1))
    q = np.diag([1e-4, 4e-4])
    np.testing.assert_allclose(ekf.predict_covariance(p, f, g, q), f @ p @ f.T + g @ q @ g.T)


def test_joseph_update_equals_the_textbook_kalman_update():
    rng = np.random.default_rng(35)
    a = rng.normal(size=(3, 3))
    p = a @ a.T + np.eye(3)
    h = rng.normal(size=(2, 3))
    r = np.diag([0.5, 0.2])
    x, nu = rng.normal(size=3), rng.normal(size=2)
    ph, s, s_inv = ekf.innovation(p, h, r)
    np.testing.assert_allclose(s, h @ p @ h.T + r)
    np.testing.assert_allclose(s_inv @ s, np.eye(2), atol=1e-12)
    assert ekf.nis(nu, s_inv) == pytest.approx(float(nu @ np.linalg.solve(s, nu)))
    x1, p1 = ekf.joseph_update(x, p, nu, h, r, ph, s_inv)
    k = p @ h.T @ np.linalg.inv(s)
    np.testing.assert_allclose(x1, x + k @ nu)
    np.testing.assert_allclose(p1, (np.eye(3) - k @ h) @ p, atol=1e-12)
