"""The MRCLAM EKF (localization/mrclam_ekf.py): every Jacobian against finite differences,
covariance intersection (optimal weight, consistent under any correlation), the AR(1)
inflation, gating, and a real-data slice of Dataset 6 scored against the truth; the
integrity counts of localization/ekf.py."""

from __future__ import annotations

import math
from collections import Counter

import numpy as np
import pytest
from numjac import numeric_jacobian

from localization.covariance_intersection import (
    ci_posterior,
    ci_update,
    ci_weight,
    split_ci_posterior,
    split_ci_update,
    split_ci_weight,
)
from localization.ekf import BoxTrack, integrity_counts
from localization.mrclam import MrclamRun, RobotRun, load_mrclam
from localization.mrclam_camera import camera_measurement, target_position
from localization.mrclam_ekf import (
    EkfTrack,
    MrclamEkfConfig,
    ar1_inflation,
    run_ekf,
    score_track,
)
from localization.mrclam_filter import JointEkf, frame_factor
from localization.mrclam_motion import NX, biased_motion, velocity_motion
from numerics.motion import motion
from numerics.rangebearing import range_bearing
from tests.conftest import SHARED, require

DATA = SHARED / "data/mrclam/MRCLAM_Dataset6"


def _poses(rng, n):
    return rng.uniform([-5, -5, -7], [5, 5, 7], (n, 3))


def test_velocity_motion_jacobians_match_finite_differences():
    rng = np.random.default_rng(1)
    for s in _poses(rng, 60):
        v, w = rng.uniform(-0.3, 0.3), rng.choice([0.0, 1e-7, rng.uniform(-1.0, 1.0)])
        dt = rng.uniform(0.001, 1.5)
        _, f, g = velocity_motion(s, v, w, dt)
        nf = numeric_jacobian(lambda x, v=v, w=w, dt=dt: velocity_motion(x, v, w, dt)[0], s)
        ng = numeric_jacobian(
            lambda u, s=s, dt=dt: velocity_motion(s, u[0], u[1], dt)[0], np.array([v, w])
        )
        np.testing.assert_allclose(f, nf, atol=1e-6)
        np.testing.assert_allclose(g, ng, atol=1e-6)


def _state(rng, s):
    """A full state around the pose s: biases, camera terms and common errors."""
    sig = [0.03, 0.05, 0.05, 0.05, 0.01, 0.03, 0.05, 0.005, 0.005]
    return np.concatenate([s, rng.normal(0.0, sig)])


def test_biased_motion_jacobians_match_finite_differences():
    rng = np.random.default_rng(7)
    for s in _poses(rng, 60):
        x = _state(rng, s)
        v, w = rng.uniform(-0.3, 0.3), rng.choice([0.0, 1e-7, rng.uniform(-1.0, 1.0)])
        dt, tau = rng.uniform(0.001, 1.5), rng.choice([0.0, 120.0])
        taus = (15.0, 12.0) if tau else (0.0, 0.0)
        x1, f, g = biased_motion(x, v, w, dt, tau, taus)
        assert x1.shape == (NX,) and f.shape == (NX, NX) and g.shape == (NX, 2)
        np.testing.assert_allclose(
            x1[:3], motion(s, np.array([v * (1 + x[3]) * dt, w * (1 + x[4]) * dt]), 0.5, True)
        )
        np.testing.assert_allclose(x1[5:10], x[5:10])  # the camera's calibration stays
        nf = numeric_jacobian(lambda y, v=v, w=w, dt=dt, tau=tau, taus=taus: biased_motion(
            y, v, w, dt, tau, taus)[0], x)  # fmt: skip
        ng = numeric_jacobian(
            lambda u, x=x, dt=dt, tau=tau: biased_motion(x, u[0], u[1], dt, tau)[0],
            np.array([v, w]),
        )
        np.testing.assert_allclose(f, nf, atol=1e-6)
        # G is the Jacobian in the commands of the pose rows (the noise enters there).
        np.testing.assert_allclose(g[:3], ng[:3], atol=1e-6)


@pytest.mark.parametrize("model", ["depth", "range"])
@pytest.mark.parametrize("measured_bearing", [False, True])
def test_camera_model_jacobians_match_finite_differences(model, measured_bearing):
    """d(rho, psi)/d state and d(rho, psi)/d target, with the range factor taken at the
    predicted bearing or at a measured one (then T moves the bearing noise into the
    range: T R T^T is the covariance of the linearised range and bearing errors)."""
    rng = np.random.default_rng(11)
    for s in _poses(rng, 150):
        x = _state(rng, s)
        m = rng.uniform(-6, 6, 2)
        if np.hypot(*(m - s[:2])) < 0.3:
            continue
        psi_m = rng.uniform(-0.6, 0.6) if measured_bearing else None
        z, hs, hm, t = camera_measurement(x, *m, model, psi_m)
        assert hs.shape == (2, NX) and hm.shape == (2, 2)
        ns = numeric_jacobian(lambda y, m=m, q=psi_m: camera_measurement(y, *m, model, q)[0],
                              x, angular_out=(1,))  # fmt: skip
        nm = numeric_jacobian(lambda p, x=x, q=psi_m: camera_measurement(x, *p, model, q)[0],
                              m, angular_out=(1,))  # fmt: skip
        np.testing.assert_allclose(hs, ns, atol=1e-6)
        np.testing.assert_allclose(hm, nm, atol=1e-6)
        if measured_bearing:  # T[0, 1] = -d rho / d psi at psi_m
            drho = numeric_jacobian(
                lambda q, x=x, m=m: camera_measurement(x, *m, model, q[0])[0][:1],
                np.array([psi_m]),
            )
            assert abs(t[0, 1] + drho[0, 0]) < 1e-6 and t[1, 0] == 0.0
        else:
            assert np.array_equal(t, np.eye(2))


def test_camera_reports_the_depth_and_its_inverse_finds_the_target():
    """Straight ahead the depth is the range; 0.5 rad off it is r cos(0.5) (what makes
    Dataset 6's ranges 12 % short at the edge of the image); target_position inverts
    the model, with its Jacobians against finite differences."""
    s = np.zeros(NX)
    z, *_ = camera_measurement(s, 3.0, 0.0)
    np.testing.assert_allclose(z, [3.0, 0.0])
    z, *_ = camera_measurement(s, 3.0 * math.cos(0.5), 3.0 * math.sin(0.5))
    np.testing.assert_allclose(z, [3.0 * math.cos(0.5), 0.5])
    rng = np.random.default_rng(12)
    for model in ("depth", "range"):
        for s in _poses(rng, 100):
            x = _state(rng, s)
            m = rng.uniform(-6, 6, 2)
            if np.hypot(*(m - s[:2])) < 0.3:
                continue
            z, *_ = camera_measurement(x, *m, model)
            inv = target_position(x, z, model)
            if abs(z[1]) >= 1.2 and model == "depth":
                assert inv is None
                continue
            p, js, jz = inv
            np.testing.assert_allclose(p, m, atol=1e-9)
            nj = numeric_jacobian(lambda y, z=z, md=model: target_position(y, z, md)[0], x)
            nz = numeric_jacobian(lambda q, x=x, md=model: target_position(x, q, md)[0], z)
            np.testing.assert_allclose(js, nj, atol=1e-5)
            np.testing.assert_allclose(jz, nz, atol=1e-5)
    assert target_position(np.zeros(NX), np.array([0.01, 0.0]) - [0.02, 0.0]) is None


def test_velocity_motion_follows_the_arc():
    s1, _, _ = velocity_motion(np.array([1.0, 2.0, 0.0]), 0.5, math.pi, 1.0)  # half a turn
    np.testing.assert_allclose(s1, [1.0, 2.0 + 2 * 0.5 / math.pi, math.pi], atol=1e-12)


def test_landmark_measurement_jacobians_match_finite_differences():
    rng = np.random.default_rng(2)
    for s in _poses(rng, 100):
        m = rng.uniform(-6, 6, 2)
        if np.hypot(*(m - s[:2])) < 0.1:
            continue
        z, hs, hm = range_bearing(s, *m)
        assert z[0] > 0 and -math.pi < z[1] <= math.pi
        ns = numeric_jacobian(lambda x, m=m: range_bearing(x, *m)[0], s, angular_out=(1,))
        nm = numeric_jacobian(lambda p, s=s: range_bearing(s, *p)[0], m, angular_out=(1,))
        np.testing.assert_allclose(hs, ns, atol=1e-6)
        np.testing.assert_allclose(hm, nm, atol=1e-6)


def test_robot_to_robot_jacobians_wrt_both_poses():
    """h(s_i, s_j) = range and bearing of robot j's position seen from pose s_i; the
    filter uses d h / d s_i = H_s and d h / d s_j = [H_m, 0]."""
    rng = np.random.default_rng(3)
    for si, sj in zip(_poses(rng, 80), _poses(rng, 80), strict=True):
        if np.hypot(*(sj[:2] - si[:2])) < 0.1:
            continue
        _, hs, hm = range_bearing(si, sj[0], sj[1])
        hj = np.hstack([hm, np.zeros((2, 1))])
        ni = numeric_jacobian(
            lambda x, sj=sj: range_bearing(x, sj[0], sj[1])[0], si, angular_out=(1,)
        )
        nj = numeric_jacobian(
            lambda x, si=si: range_bearing(si, x[0], x[1])[0], sj, angular_out=(1,)
        )
        np.testing.assert_allclose(hs, ni, atol=1e-6)
        np.testing.assert_allclose(hj, nj, atol=1e-6)


def _spd(rng, n, scale=1.0):
    a = rng.normal(size=(n, n)) * scale
    return a @ a.T + 1e-3 * np.eye(n)


@pytest.mark.parametrize("criterion", ["det", "trace"])
@pytest.mark.parametrize("block", [None, 3])
def test_ci_weight_is_the_optimum_of_its_criterion(criterion, block):
    """Closed form (det) or golden section (trace; any criterion on the pose block of a
    5-state) against a fine grid of weights."""
    rng = np.random.default_rng(4)
    n = 3 if block is None else 5
    b = n if block is None else block
    grid = np.linspace(1e-3, 1.0, 2000)

    def measure(m):
        return np.linalg.det(m[:b, :b]) if criterion == "det" else np.trace(m[:b, :b])

    for _ in range(30):
        p, r = _spd(rng, n, rng.uniform(0.05, 2)), _spd(rng, 2, rng.uniform(0.05, 2))
        h = rng.normal(size=(2, n))
        w = ci_weight(p, h, r, criterion, block=block)
        assert 0.0 < w <= 1.0
        best = min(measure(ci_posterior(p, h, r, g)) for g in grid)
        assert measure(ci_posterior(p, h, r, w)) <= best * (1 + 1e-5) + 1e-15


def test_ci_ignores_a_weak_measurement_and_uses_a_strong_one():
    p, h = np.eye(3), np.array([[1.0, 0, 0], [0, 1.0, 0]])
    assert ci_weight(p, h, np.eye(2) * 10.0) == 1.0  # sum of lambda = 0.2 <= 3
    w = ci_weight(p, h, np.eye(2) * 1e-3)
    assert w < 0.5
    x, pp = ci_update(np.zeros(3), p, np.array([1.0, 0.0]), h, np.eye(2) * 1e-3, w)
    assert x[0] > 0.5 and np.linalg.det(pp) < np.linalg.det(p)


def test_ci_is_consistent_for_any_correlation():
    """The CI covariance bounds the true error covariance of its estimate whatever the
    cross-covariance between the prior and the measurement errors."""
    rng = np.random.default_rng(5)
    for _ in range(200):
        p, r = _spd(rng, 3, rng.uniform(0.1, 1)), _spd(rng, 2, rng.uniform(0.1, 1))
        h = rng.normal(size=(2, 3))
        # A joint covariance [[P, C], [C^T, R]] with an arbitrary valid C.
        lp, lr = np.linalg.cholesky(p), np.linalg.cholesky(r)
        q = np.linalg.qr(rng.normal(size=(3, 3)))[0][:, :2] * rng.uniform(0, 1)
        c = lp @ q @ lr.T
        joint = np.block([[p, c], [c.T, r]])
        w = ci_weight(p, h, r, "det")
        if w >= 1.0:
            continue
        pw, rw = p / w, r / (1 - w)
        k = pw @ h.T @ np.linalg.inv(h @ pw @ h.T + rw)
        a = np.hstack([np.eye(3) - k @ h, k])  # error of x+ = (I - K H) e_x + K e_z
        true_cov = a @ joint @ a.T
        assert np.linalg.eigvalsh(ci_posterior(p, h, r, w) - true_cov).min() > -1e-9


def _correlated(rng, p, r):
    """A joint covariance [[P, C], [C^T, R]] with an arbitrary valid cross-covariance."""
    lp, lr = np.linalg.cholesky(p), np.linalg.cholesky(r)
    n, m = p.shape[0], r.shape[0]
    q = np.linalg.qr(rng.normal(size=(n, n)))[0][:, :m] * rng.uniform(0, 1)
    c = lp @ q @ lr.T
    return np.block([[p, c], [c.T, r]])


def test_split_ci_is_consistent_for_any_correlation_of_the_dependent_part():
    """SCI with a measurement error e_d + e_i, e_d arbitrarily correlated with the prior
    and e_i independent: the SCI covariance bounds the true error covariance of its
    estimate, at its optimal weight and at any other; with R_i = 0 it is CI."""
    rng = np.random.default_rng(15)
    used = 0
    for _ in range(200):
        p, rd, ri = _spd(rng, 5, rng.uniform(0.1, 1)), _spd(rng, 2, 0.5), _spd(rng, 2, 0.3)
        h = rng.normal(size=(2, 5))
        joint = _correlated(rng, p, rd)
        for w in (split_ci_weight(p, h, rd, ri, "det", 3), rng.uniform(0.05, 0.95)):
            if w >= 1.0:
                continue
            used += 1
            pw, rw = p / w, rd / (1 - w) + ri
            k = pw @ h.T @ np.linalg.inv(h @ pw @ h.T + rw)
            a = np.hstack([np.eye(5) - k @ h, k])  # x+ error: (I - K H) e_x + K e_d (+ K e_i)
            true_cov = a @ joint @ a.T + k @ ri @ k.T
            assert np.linalg.eigvalsh(split_ci_posterior(p, h, rd, ri, w) - true_cov).min() > -1e-9
    assert used > 250
    p, r, h = _spd(rng, 3), _spd(rng, 2), rng.normal(size=(2, 3))
    w = 0.4
    np.testing.assert_allclose(split_ci_posterior(p, h, r, 0 * r, w), ci_posterior(p, h, r, w))


@pytest.mark.parametrize("criterion", ["det", "trace"])
def test_split_ci_weight_is_the_optimum_on_the_pose_block(criterion):
    rng = np.random.default_rng(16)
    grid = np.linspace(1e-3, 1.0 - 1e-6, 1500)

    def measure(m):
        return np.linalg.det(m[:3, :3]) if criterion == "det" else np.trace(m[:3, :3])

    for _ in range(20):
        p, rd, ri = _spd(rng, 6, rng.uniform(0.05, 2)), _spd(rng, 2, 0.3), _spd(rng, 2, 0.3)
        h = rng.normal(size=(2, 6))
        w = split_ci_weight(p, h, rd, ri, criterion, 3)
        best = min(measure(split_ci_posterior(p, h, rd, ri, g)) for g in grid)
        best = min(best, measure(p))
        assert measure(split_ci_posterior(p, h, rd, ri, w)) <= best * (1 + 1e-4) + 1e-15
    # a measurement that knows nothing new: w = 1, the prior is kept
    p = np.eye(3) * 1e-4
    x, pp = split_ci_update(np.zeros(3), p, np.ones(2), np.eye(3)[:2], np.eye(2), np.eye(2), 1.0)
    assert split_ci_weight(p, np.eye(3)[:2], np.eye(2), np.eye(2)) == 1.0
    assert np.array_equal(x, np.zeros(3)) and pp is p


def test_frame_factor_gives_a_frame_the_information_of_its_mean():
    rho = np.array([0.0, 0.22, 0.49, 1.0])
    for k in range(1, 8):
        info = sum(1.0 / frame_factor(j, rho) for j in range(1, k + 1))
        np.testing.assert_allclose(info, k / (1.0 + (k - 1) * rho))


def test_ar1_inflation_matches_the_variance_of_a_correlated_mean():
    rng = np.random.default_rng(6)
    dt, tau, n = 0.2, 2.0, 4000
    rho = math.exp(-dt / tau)
    e = np.empty((300, n))
    e[:, 0] = rng.normal(size=300)
    for i in range(1, n):
        e[:, i] = rho * e[:, i - 1] + math.sqrt(1 - rho * rho) * rng.normal(size=300)
    ratio = e.mean(axis=1).var() * n  # variance of the mean / (1 / n)
    assert abs(ratio / ar1_inflation(dt, tau) - 1.0) < 0.2
    assert ar1_inflation(math.inf, tau) == 1.0 and ar1_inflation(dt, 0.0) == 1.0


def _cut(run: MrclamRun, a: float, b: float) -> MrclamRun:
    t0 = run.start_s

    def c(x):
        return x[(x[:, 0] >= t0 + a) & (x[:, 0] < t0 + b)]

    robots = {
        n: RobotRun(n, c(r.odometry), c(r.measurements), c(r.truth)) for n, r in run.robots.items()
    }
    return MrclamRun(run.directory, robots, run.landmarks, run.barcodes)


@pytest.fixture(scope="module")
def dataset6():
    return load_mrclam(require(DATA))


@pytest.mark.parametrize("cooperation", ["joint", "split_ci"])
def test_real_slice_is_accurate_and_consistent(dataset6, cooperation):
    """Dataset 6, 60-180 s, robots 2, 3 and 5: RMSE and 3-sigma containment (measured
    joint 0.064 / 0.072 / 0.059 m, split CI 0.068 / 0.082 / 0.063 m, all 100 %)."""
    run = _cut(dataset6, 60.0, 180.0)
    cfg = MrclamEkfConfig(cooperation=cooperation)
    tracks = run_ekf(run, robots=[2, 3, 5], config=cfg)
    assert sorted(tracks) == [2, 3, 5]
    for n, tr in tracks.items():
        assert isinstance(tr, EkfTrack)
        assert tr.mean.shape == (len(tr.t), 3) and tr.cov.shape == (len(tr.t), 3, 3)
        assert np.all(np.diff(tr.t) >= 0)
        assert np.all(np.linalg.eigvalsh(tr.cov).min(axis=1) > 0)
        sc = score_track(tr, run.robots[n])
        assert sc["scored"] > 2000
        assert sc["rmse_m"] < 0.12, (n, sc)
        assert sc["containment"] >= 0.95, (n, sc)
    c = tracks[3].counts
    assert c["landmark_accepted"] > 500 and c["odometry"] > 9000
    assert c["robot_accepted"] > 20 and c["robot_not_run"] > 0  # robots 1 and 4: not run
    # Deterministic: the same inputs give the same tracks.
    again = run_ekf(run, robots=[2, 3, 5], config=cfg)
    assert all(np.array_equal(again[n].mean, tracks[n].mean) for n in tracks)


def test_covariance_intersection_finds_little_to_fuse_and_split_ci_more(dataset6):
    """Between robots that all see landmarks, CI (everything of unknown correlation)
    rarely beats a robot's own prior; split CI (the camera noise independent) does."""
    run = _cut(dataset6, 60.0, 180.0)
    counts = {}
    for mode in ("ci", "split_ci"):
        tr = run_ekf(run, robots=[2, 3, 5], config=MrclamEkfConfig(cooperation=mode))
        counts[mode] = sum((t.counts for t in tr.values()), Counter())
    assert counts["ci"]["robot_accepted"] <= 0.1 * counts["ci"]["robot_no_gain"]
    assert counts["split_ci"]["robot_accepted"] > 5 * max(counts["ci"]["robot_accepted"], 1)


def test_the_joint_filter_applies_its_lazy_cross_covariances_exactly():
    """Cross blocks are brought up to date (Phi_i P_ij Phi_j^T) only when an update needs
    them: equal to propagating the whole joint covariance at every step."""
    rng = np.random.default_rng(21)
    cfg = MrclamEkfConfig()
    f = JointEkf(cfg, {6: (3.0, 1.0, 0.01, 0.01)})
    for n in (1, 2):
        f.add_robot(n, 0.0, np.array([0.0, float(n), 0.1]), np.eye(3) * 0.01)
    a = rng.normal(size=f.P.shape)
    f.P = a @ a.T * 0.01 + np.eye(f.P.shape[0]) * 0.01  # correlated, as after an update
    f.correlated = True
    ref = f.P.copy()
    b = {n: slice(f.at[n], f.at[n] + NX) for n in (1, 2)}
    for step in range(12):
        n = 1 + step % 2
        rs = f.r[n]
        rs.v, rs.w = rng.uniform(0, 0.1), rng.uniform(-0.5, 0.5)
        t = rs.t + rng.uniform(0.01, 0.3)
        _, fn, _ = biased_motion(
            rs.s, rs.v, rs.w, t - rs.t, cfg.bias_tau_s, cfg.camera_common_tau_s
        )
        m = np.eye(ref.shape[0])
        m[b[n], b[n]] = fn
        ref = m @ ref @ m.T
        f._predict(n, t)
        ref[b[n], b[n]] = f.P[b[n], b[n]]  # the diagonal block: F P F^T + Q, kept current
    f._sync()
    np.testing.assert_allclose(f.P, ref, atol=1e-12)


def test_gross_outliers_are_gated_and_named(dataset6):
    run = _cut(dataset6, 60.0, 120.0)
    r3 = run.robots[3]
    m = r3.measurements.copy()
    lm = np.flatnonzero(m[:, 1] >= 6)[50]
    bad = m[lm].copy()
    bad[0] += 0.01
    bad[3] = bad[3] + math.pi  # the landmark behind the robot
    nan = bad.copy()
    nan[0] += 0.01
    nan[2] = np.nan
    unknown = bad.copy()
    unknown[0] += 0.02
    unknown[1] = 99
    m = np.vstack([m, bad, nan, unknown])
    m = m[np.argsort(m[:, 0], kind="stable")]
    robots = dict(run.robots)
    robots[3] = RobotRun(3, r3.odometry, m, r3.truth)
    run = MrclamRun(run.directory, robots, run.landmarks, run.barcodes)
    tr = run_ekf(run, robots=[3], cooperative=False)[3]
    assert any(abs(t - bad[0]) < 1e-9 and s == int(bad[1]) and d2 > 100 for t, s, d2 in tr.gated)
    assert tr.counts["landmark_gated"] == len([g for g in tr.gated if g[1] >= 6])
    assert tr.counts["invalid"] == 1 and tr.counts["unknown_subject"] == 1
    assert tr.counts["robot_not_run"] > 0 and tr.counts["robot_ignored"] == 0
    assert score_track(tr, run.robots[3])["containment"] >= 0.95


def test_bad_arguments_get_clear_errors(dataset6):
    with pytest.raises(ValueError, match="robot 9 is not in"):
        run_ekf(dataset6, robots=[9])
    with pytest.raises(ValueError, match="gate_probability"):
        MrclamEkfConfig(gate_probability=1.0)
    with pytest.raises(ValueError, match="ci_criterion"):
        MrclamEkfConfig(ci_criterion="max")
    assert abs(MrclamEkfConfig(gate_probability=0.999).gate - 13.8155) < 1e-3


def _track(t, mean, sig):
    mean = np.asarray(mean, float)
    cov = np.array([np.diag(np.square(s)) for s in sig], float)
    return EkfTrack(1, np.asarray(t, float), mean, cov)


def test_integrity_counts_definitions():
    # EKF at (0, 0, 0) with sigma 0.1 (3-sigma region +/-0.3), from t = 1.
    tr = _track([1.0], [[0.0, 0.0, 0.0]], [[0.1, 0.1, 0.1]])
    t = np.array([0.5, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    lo = np.array(
        [
            [-1, -1, -1],  # before the first estimate: no_estimate
            [-1, -1, -1],  # box around everything, truth inside both: fine
            [0.5, -1, -1],  # box beside the 3-sigma region, truth in the EKF region: false alarm
            [0.5, -1, -1],  # same box, truth in the box (EKF wrong): true alarm
            [0.2, -1, -1],  # overlapping, the mean outside the box: estimate alarm only
            [-1, -1, 2 * math.pi - 1],  # heading box on another branch: no alarm
            [1.0, 1.0, 0.0],  # empty (lo > hi)
        ],
        float,
    )
    hi = np.array(
        [[1, 1, 1], [1, 1, 1], [1, 1, 1], [1, 1, 1], [1, 1, 1], [1, 1, 2 * math.pi + 1], [0, 0, 0]],
        float,
    )
    truth = np.array(
        [[0, 0, 0], [0, 0, 0], [0.1, 0, 0], [0.7, 0, 0], [0.25, 0, 0], [0.0, 0.0, 0.5], [0, 0, 0]],
        float,
    )
    has = np.array([1, 1, 1, 1, 1, 1, 1], bool)
    c = integrity_counts(tr, BoxTrack(t, lo, hi), (truth, has))
    assert c == {
        "checked": 5,
        "no_estimate": 1,
        "empty_boxes": 1,
        "scored": 5,
        "alarms": 2,
        "estimate_alarms": 3,
        "false_alarms": 1,
        "true_alarms": 1,
        "missed_alarms": 1,
        "estimate_false_alarms": 2,
        "ekf_misses": 2,
        "box_misses": 1,
    }
    # Without truth nothing is scored, the alarms stay.
    c = integrity_counts(tr, BoxTrack(t, lo, hi), (truth, ~has))
    assert c["scored"] == 0 and c["alarms"] == 2 and c["false_alarms"] == 0
    with pytest.raises(ValueError, match="must be"):
        integrity_counts(tr, BoxTrack(t, lo[:3], hi), (truth, has))
