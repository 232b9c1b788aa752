"""Data association: vectorised gating, NN, JCBB on an ambiguous case, the new-landmark
threshold and the tentative list."""

from __future__ import annotations

import numpy as np
import pytest

from mapping.slam.association import (
    CHI2_2DOF_99,
    TentativeLandmarks,
    classify_unmatched,
    mahalanobis_matrix,
    nearest_neighbour,
)
from mapping.slam.ekf import EkfSlam
from mapping.slam.jcbb import jcbb
from mapping.slam.models import UnicycleModel
from mapping.slam.service import LandmarkSlam, SlamConfig
from msgs import LandmarkScan
from numerics.angles import wrap


def test_mahalanobis_matrix_matches_loop():
    rng = np.random.default_rng(0)
    z = np.stack([rng.uniform(1, 20, 5), rng.uniform(-3, 3, 5)], 1)
    zp = np.stack([rng.uniform(1, 20, 4), rng.uniform(-3, 3, 4)], 1)
    a = rng.normal(size=(4, 2, 2))
    s = a @ a.transpose(0, 2, 1) + 0.1 * np.eye(2)
    d2 = mahalanobis_matrix(z, zp, s)
    for i in range(5):
        for j in range(4):
            nu = z[i] - zp[j]
            nu[1] = wrap(nu[1])
            assert d2[i, j] == pytest.approx(nu @ np.linalg.solve(s[j], nu))


def test_bearing_wraps_in_gating():
    s = np.array([np.diag([0.1, 0.01])])
    d2 = mahalanobis_matrix(np.array([[5.0, np.pi - 0.01]]), np.array([[5.0, -np.pi + 0.01]]), s)
    assert d2[0, 0] == pytest.approx(0.02**2 / 0.01)


def test_nearest_neighbour_gate_and_uniqueness():
    d2 = np.array(
        [
            [0.5, 3.0, 50.0],
            [0.4, 8.0, 60.0],  # both want landmark 0; the closer pair wins
            [40.0, 30.0, 20.0],  # outside the gate of every landmark
        ]
    )
    assoc = nearest_neighbour(d2, CHI2_2DOF_99)
    assert list(assoc) == [1, 0, -1]
    # new-landmark threshold: obs 2 is farther than 13.8 from all -> new; obs 0/1 matched
    assert list(classify_unmatched(d2, assoc, 13.8)) == [False, False, True]
    # between gate and threshold: ambiguous, neither matched nor new
    d2b = np.array([[11.0, 40.0]])
    a = nearest_neighbour(d2b, CHI2_2DOF_99)
    assert a[0] == -1 and not classify_unmatched(d2b, a, 13.8)[0]
    assert list(nearest_neighbour(np.zeros((2, 0)))) == [-1, -1]


def ambiguous_filter() -> tuple[EkfSlam, np.ndarray]:
    """Two landmarks 0.2 rad apart at 10 m, then a large heading uncertainty; the truth is
    a heading error of -0.16 rad, so both observations shift by +0.16 rad."""
    ekf = EkfSlam(
        UnicycleModel(),
        x0=np.zeros(3),
        p0=np.diag([1e-6, 1e-6, 1e-8]),
        r=np.diag([0.05**2, 0.01**2]),
        bearing_offset=0.0,
    )
    ekf.augment(np.array([[10.0, 0.0], [10.0, 0.2]]))
    ekf.predict(np.zeros(2), 0.0, np.diag([1e-10, 0.15**2]))
    z = np.array([[10.0, 0.16], [10.0, 0.36]])
    return ekf, z


def test_jcbb_beats_nn_on_ambiguous_case():
    ekf, z = ambiguous_filter()
    zp, _, _, s = ekf.predict_observations()
    d2 = mahalanobis_matrix(z, zp, s)
    nn = nearest_neighbour(d2, CHI2_2DOF_99)
    assert nn[0] == 1  # NN takes the nearer, wrong landmark for observation 0
    zj, hph = ekf.joint_innovation_covariance(np.arange(2))
    jc = jcbb(z, zj, hph, ekf.r, d2, CHI2_2DOF_99)
    assert list(jc) == [0, 1]


def test_jcbb_rejects_jointly_incompatible_pair():
    """Innovations in opposite directions are individually fine but jointly not."""
    ekf, _ = ambiguous_filter()
    z = np.array([[10.0, -0.2], [10.0, 0.4]])  # -0.2 and +0.2 rad: no common heading error
    zp, _, _, s = ekf.predict_observations()
    d2 = mahalanobis_matrix(z, zp, s)
    zj, hph = ekf.joint_innovation_covariance(np.arange(2))
    jc = jcbb(z, zj, hph, ekf.r, d2, CHI2_2DOF_99)
    assert np.count_nonzero(jc >= 0) == 1


def test_service_with_jcbb_uses_the_joint_answer():
    """Through the service: with JCBB the two landmarks keep their 2 m spacing (right
    pairs, the error is absorbed by the heading); NN's swapped pairs pull them together."""
    _, z = ambiguous_filter()
    spacing = {}
    for method in ("nn", "jcbb"):
        slam = LandmarkSlam(SlamConfig(vehicle="unicycle", association=method, max_range_m=50))
        slam.ekf = ambiguous_filter()[0]  # its bearing_offset (0) is the one process() uses
        slam.process(z)
        lm = slam.ekf.landmarks
        spacing[method] = float(np.hypot(*(lm[1] - lm[0])))
        assert slam.stats.matched == 2
    assert spacing["jcbb"] == pytest.approx(10 * 2 * np.sin(0.1), abs=0.02)
    assert abs(spacing["nn"] - spacing["jcbb"]) > 0.5


def test_tentative_list_confirms_after_k_sightings():
    t = TentativeLandmarks(confirm_after=3, max_age_scans=5)
    cov = np.array([np.eye(2) * 0.01])
    assert not t.observe(np.array([[1.0, 1.0]]), cov, scan=1).any()
    assert not t.observe(np.array([[1.05, 0.98]]), cov, scan=2).any()
    assert t.observe(np.array([[0.97, 1.02]]), cov, scan=3).all()
    assert len(t) == 0  # promoted candidates leave the list
    # a one-off detection expires
    t.observe(np.array([[5.0, 5.0]]), cov, scan=4)
    t.observe(np.zeros((0, 2)), np.zeros((0, 2, 2)), scan=20)
    assert len(t) == 0 and t.expired == 1


def static_slam(confirm_after: int) -> LandmarkSlam:
    cfg = SlamConfig(
        vehicle="unicycle",
        sigma_range_m=0.05,
        sigma_bearing_rad=0.01,
        confirm_after=confirm_after,
        max_range_m=30.0,
    )
    return LandmarkSlam(cfg)


def test_single_spurious_detection_never_enters_the_map():
    rng = np.random.default_rng(7)
    truth = np.array([[5.0, 1.0], [8.0, -3.0], [3.0, 4.0]])
    for k, expected in ((3, 3), (1, 4)):
        slam = static_slam(k)
        for scan in range(6):
            r = np.hypot(truth[:, 0], truth[:, 1]) + rng.normal(0, 0.05, 3)
            b = np.arctan2(truth[:, 1], truth[:, 0]) + rng.normal(0, 0.01, 3)
            if scan == 2:  # one spurious detection, far from everything
                r = np.append(r, 12.0)
                b = np.append(b, -1.0)
            msg = LandmarkScan(scan * 10**8, tuple(r), tuple(b), bearing_zero="x")
            _, lmap = slam.on_scan(msg)
        assert len(lmap.ids) == expected  # k=1 shows the spurious one would have entered
        if k == 3:
            np.testing.assert_allclose(np.c_[lmap.xs, lmap.ys], truth, atol=0.2)
            assert slam.stats.promoted == 3
