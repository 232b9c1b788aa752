"""EKF-SLAM filter: the block/sparse forms equal the dense textbook EKF (slam-ekf.txt
§4.2.2-4.2.4), augmentation, and the vectorised gating covariances."""

from __future__ import annotations

import numpy as np
import pytest

from mapping.slam.ekf import EkfSlam
from mapping.slam.models import HALF_PI, AckermannModel, inverse_observe, observe
from numerics.angles import wrap


def make_filter(seed: int = 0, n: int = 5) -> tuple[EkfSlam, np.random.Generator]:
    rng = np.random.default_rng(seed)
    ekf = EkfSlam(
        AckermannModel(),
        x0=np.array([1.0, 2.0, 0.3]),
        p0=np.diag([0.1, 0.2, 0.01]),
        r=np.diag([0.3**2, np.deg2rad(2.0) ** 2]),
        bearing_offset=HALF_PI,
    )
    z = np.stack([rng.uniform(5, 30, n), rng.uniform(0.2, np.pi - 0.2, n)], 1)
    ekf.augment(z)
    return ekf, rng


def dense_augment(x, p, xv_idx, z, r, offset):
    """The paper's P_a = J P_aug J' with the full augmentation Jacobian (§4.2.4)."""
    n = len(x)
    m, gx, gz = inverse_observe(x[:3], z[None], offset)
    paug = np.zeros((n + 2, n + 2))
    paug[:n, :n] = p
    paug[n:, n:] = r
    j = np.zeros((n + 2, n + 2))
    j[:n, :n] = np.eye(n)
    j[n:, :3] = gx[0]
    j[n:, n:] = gz[0]
    return np.concatenate([x, m[0]]), j @ paug @ j.T


def test_augmentation_matches_dense_jacobian():
    ekf = EkfSlam(AckermannModel(), x0=np.array([0.5, -1.0, 1.0]), p0=np.diag([0.2, 0.3, 0.05]))
    x, p = ekf.state, ekf.covariance
    rng = np.random.default_rng(1)
    for _ in range(4):
        z = np.array([rng.uniform(2, 20), rng.uniform(0, np.pi)])
        x, p = dense_augment(x, p, None, z, ekf.r, HALF_PI)
        ids = ekf.augment(z)
        np.testing.assert_allclose(ekf.state, x, atol=1e-12)
        np.testing.assert_allclose(ekf.covariance, p, atol=1e-12)
    assert ekf.n_landmarks == 4 and ekf.ids == [0, 1, 2, 3] and ids == [3]
    # the new landmark sits where the observation says
    zz, _, _ = observe(ekf.vehicle, ekf.landmarks[-1:], HALF_PI)
    assert zz[0, 0] == pytest.approx(z[0])
    assert np.all(np.linalg.eigvalsh(ekf.covariance) > 0)


def test_block_prediction_matches_full_jacobian():
    ekf, rng = make_filter()
    x, p = ekf.state, ekf.covariance
    n = len(x)
    for _ in range(7):  # several predictions: the lazy cross-covariance product
        u = np.array([rng.uniform(0, 5), rng.uniform(-0.4, 0.4)])
        q = np.diag([0.3**2, 0.05**2])
        xv, f, g = ekf.model.predict(x[:3], u, 0.025)
        fj = np.eye(n)
        fj[:3, :3] = f
        gj = np.zeros((n, 2))
        gj[:3] = g
        p = fj @ p @ fj.T + gj @ q @ gj.T
        x = x.copy()
        x[:3] = xv
        x[2] = wrap(x[2])
        ekf.predict(u, 0.025, q)
    np.testing.assert_allclose(ekf.state, x, atol=1e-12)
    np.testing.assert_allclose(ekf.covariance, p, atol=1e-12)


def dense_h(ekf: EkfSlam, idx: np.ndarray) -> np.ndarray:
    n = ekf.size
    _, hv, hm = observe(ekf.vehicle, ekf.landmarks[idx], ekf.bearing_offset)
    h = np.zeros((2 * len(idx), n))
    for k, i in enumerate(idx):
        h[2 * k : 2 * k + 2, :3] = hv[k]
        h[2 * k : 2 * k + 2, 3 + 2 * i : 5 + 2 * i] = hm[k]
    return h


def test_sparse_batch_update_matches_dense_ekf():
    ekf, rng = make_filter(seed=2, n=6)
    ekf.predict(np.array([3.0, 0.1]), 0.1, np.diag([0.5**2, 0.05**2]))
    idx = np.array([4, 1, 3])
    x, p = ekf.state, ekf.covariance
    h = dense_h(ekf, idx)
    zp, _, _ = observe(ekf.vehicle, ekf.landmarks[idx], ekf.bearing_offset)
    z = zp + rng.normal(0, [0.3, 0.03], zp.shape)
    nu = z - zp
    nu[:, 1] = wrap(nu[:, 1])
    s = h @ p @ h.T + np.kron(np.eye(3), ekf.r)
    k = p @ h.T @ np.linalg.inv(s)
    x_dense = x + k @ nu.ravel()
    p_dense = p - k @ s @ k.T
    nis = ekf.update(z, idx)
    np.testing.assert_allclose(ekf.state, x_dense, atol=1e-10)
    np.testing.assert_allclose(ekf.covariance, p_dense, atol=1e-10)
    assert nis == pytest.approx(nu.ravel() @ np.linalg.solve(s, nu.ravel()))
    # the update shrinks the vehicle uncertainty
    assert np.trace(ekf.vehicle_cov) < np.trace(p[:3, :3])
    with pytest.raises(ValueError, match="twice"):
        ekf.update(z[:2], np.array([1, 1]))


def test_gating_covariances_match_dense():
    ekf, _ = make_filter(seed=3, n=7)
    ekf.predict(np.array([2.0, -0.2]), 0.2, np.diag([0.5**2, 0.05**2]))
    idx = np.array([0, 2, 5, 6])
    zp, hv, hm, s = ekf.predict_observations(idx)
    p = ekf.covariance
    for k, i in enumerate(idx):
        h = dense_h(ekf, np.array([i]))
        np.testing.assert_allclose(s[k], h @ p @ h.T + ekf.r, atol=1e-12)
    zj, hph = ekf.joint_innovation_covariance(idx)
    h = dense_h(ekf, idx)
    np.testing.assert_allclose(hph, h @ p @ h.T, atol=1e-12)
    np.testing.assert_allclose(zj, zp)
    # all landmarks by default
    assert ekf.predict_observations()[3].shape == (7, 2, 2)


def test_landmark_covariances_are_the_diagonal_blocks():
    ekf, _ = make_filter(seed=4, n=3)
    p = ekf.covariance
    blocks = ekf.landmark_covariances()
    for i in range(3):
        np.testing.assert_allclose(blocks[i], p[3 + 2 * i : 5 + 2 * i, 3 + 2 * i : 5 + 2 * i])


def test_bad_noise_shape_is_rejected():
    with pytest.raises(ValueError, match="2x2"):
        EkfSlam(AckermannModel(), r=np.eye(3))
