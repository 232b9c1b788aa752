"""Every Jacobian of the EKF-SLAM models against central finite differences."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numjac import numeric_jacobian

from mapping.slam.models import (
    HALF_PI,
    AckermannGeometry,
    AckermannModel,
    UnicycleModel,
    inverse_observe,
    observe,
)
from numerics.angles import wrap

EPS = 1e-6


def numjac(f, x: np.ndarray, angular_out: tuple[int, ...] = ()) -> np.ndarray:
    return numeric_jacobian(f, x, EPS, angular_out)


GEOMS = [
    AckermannGeometry(2.83, 3.78, 0.5, 0.76),
    AckermannGeometry(2.83, 0.95, -0.3, 0.0),
    AckermannGeometry(1.2, 0.0, 0.0, 0.4),
]


@pytest.mark.parametrize("geom", GEOMS)
@pytest.mark.parametrize(
    "xv,u,dt",
    [
        ((1.0, -2.0, 0.3), (3.0, 0.2), 0.025),
        ((0.0, 0.0, 2.9), (-1.5, -0.45), 0.1),
        ((5.0, 4.0, -1.7), (6.0, 0.0), 0.5),
    ],
)
def test_ackermann_jacobians(geom, xv, u, dt):
    model = AckermannModel(geom)
    xv, u = np.array(xv), np.array(u)
    _, fx, fu = model.predict(xv, u, dt)
    np.testing.assert_allclose(fx, numjac(lambda v: model.predict(v, u, dt)[0], xv), atol=1e-7)
    np.testing.assert_allclose(fu, numjac(lambda w: model.predict(xv, w, dt)[0], u), atol=1e-7)


def test_ackermann_kinematics():
    """Circle of the rear axle: radius L / tan(steer); the laser (a ahead, b left) keeps a
    fixed offset; the encoder speed is converted to the axle centre."""
    g = AckermannGeometry(2.83, 3.78, 0.5, 0.76)
    model = AckermannModel(g)
    steer, ve, dt = 0.2, 2.0, 0.001
    vc = model.axle_speed(ve, steer)
    assert vc == pytest.approx(ve / (1 - math.tan(steer) * 0.76 / 2.83))
    assert vc > ve  # turning left, the left wheel is the slower one
    # start with the rear axle at the origin heading +x: laser at (a, b)
    x = np.array([g.laser_ahead_m, g.laser_left_m, 0.0])
    t_total = 2.0
    for _ in range(int(t_total / dt)):
        x, _, _ = model.predict(x, np.array([ve, steer]), dt)
    th = vc * math.tan(steer) / g.wheelbase_m * t_total
    assert x[2] == pytest.approx(th, rel=1e-9)
    # rear axle on its circle about (0, R)
    rad = g.wheelbase_m / math.tan(steer)
    axle = np.array([rad * math.sin(th), rad - rad * math.cos(th)])
    c, s = math.cos(th), math.sin(th)
    laser = axle + np.array([g.laser_ahead_m * c - g.laser_left_m * s,
                             g.laser_ahead_m * s + g.laser_left_m * c])  # fmt: skip
    np.testing.assert_allclose(x[:2], laser, atol=5e-3)  # Euler at 1 kHz


@pytest.mark.parametrize("xv,u", [((1.0, 2.0, 0.4), (0.3, 0.1)), ((0, 0, -3.0), (-0.2, -0.5))])
def test_unicycle_jacobians(xv, u):
    model = UnicycleModel()
    xv, u = np.array(xv, float), np.array(u, float)
    _, fx, fu = model.predict(xv, u)
    np.testing.assert_allclose(fx, numjac(lambda v: model.predict(v, u)[0], xv), atol=1e-7)
    np.testing.assert_allclose(fu, numjac(lambda w: model.predict(xv, w)[0], u), atol=1e-7)


@pytest.mark.parametrize("offset", [HALF_PI, 0.0])
def test_observation_jacobians(offset):
    rng = np.random.default_rng(3)
    for _ in range(10):
        xv = rng.uniform(-5, 5, 3)
        m = xv[:2] + rng.uniform(-20, 20, 2)
        z, hv, hm = observe(xv, m[None], offset)
        f_x = lambda v, m=m: observe(v, m[None], offset)[0][0]  # noqa: E731
        f_m = lambda mm, xv=xv: observe(xv, mm[None], offset)[0][0]  # noqa: E731
        np.testing.assert_allclose(hv[0], numjac(f_x, xv, (1,)), atol=1e-6)
        np.testing.assert_allclose(hm[0], numjac(f_m, m, (1,)), atol=1e-6)


def test_observation_convention():
    """+pi/2 laser: a landmark straight ahead reads pi/2, one on the left reads pi."""
    xv = np.array([1.0, 1.0, 0.5])
    ahead = xv[:2] + 10 * np.array([math.cos(0.5), math.sin(0.5)])
    left = xv[:2] + 10 * np.array([math.cos(0.5 + HALF_PI), math.sin(0.5 + HALF_PI)])
    z, _, _ = observe(xv, np.stack([ahead, left]), HALF_PI)
    np.testing.assert_allclose(z[:, 0], [10, 10])
    np.testing.assert_allclose(z[:, 1], [HALF_PI, math.pi])
    z0, _, _ = observe(xv, np.stack([ahead, left]), 0.0)
    np.testing.assert_allclose(z0[:, 1], [0.0, HALF_PI], atol=1e-12)


@pytest.mark.parametrize("offset", [HALF_PI, 0.0])
def test_inverse_model_and_jacobians(offset):
    rng = np.random.default_rng(5)
    for _ in range(10):
        xv = rng.uniform(-5, 5, 3)
        z = np.array([rng.uniform(1, 40), rng.uniform(0, math.pi)])
        m, gx, gz = inverse_observe(xv, z[None], offset)
        # g inverts h
        zz, _, _ = observe(xv, m, offset)
        np.testing.assert_allclose(zz[0, 0], z[0])
        assert wrap(zz[0, 1] - z[1]) == pytest.approx(0.0, abs=1e-12)
        f_x = lambda v, z=z: inverse_observe(v, z[None], offset)[0][0]  # noqa: E731
        f_z = lambda zz, xv=xv: inverse_observe(xv, zz[None], offset)[0][0]  # noqa: E731
        np.testing.assert_allclose(gx[0], numjac(f_x, xv), atol=1e-6)
        np.testing.assert_allclose(gz[0], numjac(f_z, z), atol=1e-6)


def test_wrap():
    assert wrap(math.pi) == math.pi
    assert wrap(-math.pi) == math.pi
    np.testing.assert_allclose(
        wrap(np.array([3 * math.pi, -0.5, 7.0])), [math.pi, -0.5, 7 - 2 * math.pi]
    )
