"""The 2-D pose graph (mapping/pose_graph.py): its Jacobians against finite differences,
a loop recovered from odometry with a scale error, a wrong loop edge down-weighted."""

import math

import numpy as np
import pytest

from mapping.pose_graph import PoseGraph, edge_error, edge_jacobians
from mapping.se2 import compose, relative


def test_edge_jacobians_match_finite_differences():
    rng = np.random.default_rng(3)
    for _ in range(20):
        xi = rng.normal(size=3) * [3, 3, 2]
        xj = rng.normal(size=3) * [3, 3, 2]
        z = rng.normal(size=3) * [1, 1, 0.5]
        a, b = edge_jacobians(xi, xj)
        h = 1e-6
        for k in range(3):
            d = np.zeros(3)
            d[k] = h
            na = (edge_error(xi + d, xj, z) - edge_error(xi - d, xj, z)) / (2 * h)
            nb = (edge_error(xi, xj + d, z) - edge_error(xi, xj - d, z)) / (2 * h)
            np.testing.assert_allclose(a[:, k], na, atol=1e-6)
            np.testing.assert_allclose(b[:, k], nb, atol=1e-6)


def _square_loop(scale: float, seed: int = 1):
    """A 4 x 4 m square driven twice, nodes every 0.5 m; odometry edges with the
    distances of the first two sides of each lap scaled by ``scale`` (a pure scale error
    over a closed loop would close it: only a varying one shows), and a little noise."""
    rng = np.random.default_rng(seed)
    truth = [np.zeros(3)]
    for _lap in range(2):
        for _side in range(4):
            for k in range(8):
                turn = math.pi / 2 if k == 7 else 0.0
                truth.append(compose(truth[-1], np.array([0.5, 0.0, turn])))
    truth = np.array(truth)
    steps = relative(truth[:-1], truth[1:])
    meas = steps.copy()
    first_half = (np.arange(len(steps)) % 32) < 16
    meas[first_half, :2] *= scale
    meas += rng.normal(size=meas.shape) * [0.005, 0.005, 0.002]
    return truth, meas


def _odometry_graph(meas: np.ndarray) -> tuple[PoseGraph, np.ndarray]:
    g = PoseGraph()
    x = [np.zeros(3)]
    for m in meas:
        x.append(compose(x[-1], m))
    for p in x:
        g.add_node(p)
    info = np.diag([1 / 0.03**2, 1 / 0.01**2, 1 / 0.005**2])
    for k, m in enumerate(meas):
        g.add_edge(k, k + 1, m, info)
    return g, np.array(x)


def test_optimizer_recovers_a_loop_with_a_scale_error():
    truth, meas = _square_loop(1.08)
    g, dead = _odometry_graph(meas)
    n = len(truth)
    # One true loop edge: the last pose seen from the first (the same place, 2 laps on).
    g.add_edge(0, n - 1, relative(truth[0], truth[-1]), np.diag([400.0, 400.0, 1000.0]), True)
    sol = g.optimize()
    err_before = np.hypot(*(dead[:, :2] - truth[:, :2]).T)
    err_after = np.hypot(*(sol.poses[:, :2] - truth[:, :2]).T)
    assert err_before[-1] > 0.8  # the scale error is real: 8 % of 4 m on x and y, twice
    assert err_after[-1] < 0.1
    assert err_after.mean() < 0.5 * err_before.mean()
    assert sol.cost < sol.cost0


def test_a_wrong_loop_edge_is_down_weighted():
    truth, meas = _square_loop(1.0, seed=2)
    g, dead = _odometry_graph(meas)
    n = len(truth)
    good = np.diag([400.0, 400.0, 1000.0])
    g.add_edge(0, n - 1, relative(truth[0], truth[-1]), good, True)
    g.add_edge(8, n - 25, relative(truth[8], truth[n - 25]), good, True)
    # A wrong loop edge: node 16 claimed 2 m from where it is relative to node 48.
    wrong = relative(truth[16], truth[48]) + np.array([2.0, 0.0, 0.3])
    g.add_edge(16, 48, wrong, good, True)
    sol = g.optimize()
    assert sol.weights[-1] < 0.05  # the wrong edge hardly counts
    assert sol.weights[-3] > 0.5 and sol.weights[-2] > 0.5
    err = np.hypot(*(sol.poses[:, :2] - truth[:, :2]).T)
    assert err.max() < 0.3


def test_bad_input_is_refused():
    g = PoseGraph()
    g.add_node(np.zeros(3))
    g.add_node(np.ones(3))
    with pytest.raises(ValueError, match="finite"):
        g.add_node(np.array([0.0, math.nan, 0.0]))
    with pytest.raises(ValueError, match="unknown or equal"):
        g.add_edge(0, 2, np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match="positive definite"):
        g.add_edge(0, 1, np.zeros(3), np.diag([1.0, 0.0, 1.0]))
    assert PoseGraph().optimize().iterations == 0


def test_a_chain_of_a_thousand_nodes_solves_in_sparse_form():
    truth, meas = _square_loop(1.0, seed=4)
    meas = np.tile(meas, (16, 1))  # 32 laps of the square: 1,025 nodes
    g, dead = _odometry_graph(meas)
    n = len(g)
    g.add_edge(0, n - 1, np.zeros(3), np.diag([400.0, 400.0, 1000.0]), True)
    sol = g.optimize()
    assert n == 1025 and sol.cost < sol.cost0
    assert np.hypot(*sol.poses[-1, :2]) < 0.05  # the loop is closed


def test_the_dense_and_the_sparse_solve_agree(monkeypatch):
    """A small graph is solved in dense form (no scipy import); the sparse form, which a
    long run's graph takes, gives the same solution."""
    import mapping.pose_graph as pg

    def solved():
        truth, meas = _square_loop(1.08, seed=3)
        g, _ = _odometry_graph(meas)
        n = len(truth)
        g.add_edge(0, n - 1, relative(truth[0], truth[-1]), np.diag([400.0, 400.0, 1000.0]), True)
        g.add_edge(8, n - 9, relative(truth[0], truth[-1]) + 0.3, np.eye(3) * 50.0, True)
        return g.optimize()

    assert len(_square_loop(1.0)[0]) <= pg.DENSE_NODES
    dense = solved()
    monkeypatch.setattr(pg, "DENSE_NODES", 0)
    sparse = solved()
    assert dense.iterations == sparse.iterations > 1
    np.testing.assert_allclose(dense.poses, sparse.poses, rtol=0, atol=1e-9)
    np.testing.assert_allclose(dense.weights, sparse.weights, rtol=1e-9)
    assert dense.cost == pytest.approx(sparse.cost, rel=1e-9)
