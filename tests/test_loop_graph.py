"""The association's checks as a pose graph (mapping/loop_graph.py): the odometry edges,
the re-posing of the scans between nodes, the loop edges' anchor, and finish() with the
switch on and off on a simulated drive in the room."""

import math

import numpy as np
from ir_drive import MOUNTS, drifted, ir_scans, truth_path

from mapping.association import AssociationConfig, SampleAssociation
from mapping.grid import GridConfig
from mapping.loop_graph import LoopGraph
from mapping.se2 import compose, relative

GRID = GridConfig(resolution_m=0.1, origin_m=(-1.0, -1.0), size_m=(9.0, 9.0))
NO_HITS = np.full((1, 2), np.nan)


def _straight(graph: LoopGraph, n: int, step: float = 0.1, turn: float = 0.0) -> None:
    travel = 0.0
    for i in range(n):
        st = np.zeros(3) if i == 0 else np.array([step, 0.0, turn])
        travel += 0.0 if i == 0 else step
        graph.record(st, 0.0, travel, abs(turn) * i, 1e-6 * i, NO_HITS)


def test_odometry_edges_grow_with_distance_mostly_along_the_track():
    g = LoopGraph(AssociationConfig())
    _straight(g, 40)
    odo = g.dead_reckoned()
    z1, c1 = g.odometry_cov(odo, 0, 10)
    z2, c2 = g.odometry_cov(odo, 0, 30)
    np.testing.assert_allclose(z2, [3.0, 0.0, 0.0], atol=1e-12)
    assert c2[0, 0] > 2.5 * c1[0, 0] and c2[1, 1] > 2.5 * c1[1, 1]
    assert c2[0, 0] > 10 * c2[1, 1]  # the distance scale error dominates along the track
    assert len(g.scans) == 4 and set(np.diff(g.scans)) <= {10, 11}  # a node per metre


def test_scans_are_re_posed_between_nodes_along_their_steps():
    g = LoopGraph(AssociationConfig())
    _straight(g, 31, turn=0.01)
    odo = g.dead_reckoned()
    nodes = [0, 10, 20, 30]
    # Unchanged nodes: every scan where the steps put it.
    np.testing.assert_allclose(g._repose(nodes, odo[nodes], odo), odo, atol=1e-12)
    # Node 2 moved by 0.2 m sideways: the scans next to it follow, smoothly.
    x = odo[nodes].copy()
    x[2, 1] += 0.2
    new = g._repose(nodes, x, odo)
    np.testing.assert_allclose(new[nodes], x, atol=1e-12)
    dy = new[:, 1] - odo[:, 1]
    assert np.all(np.abs(np.diff(dy)) <= 0.021)
    assert dy[15] > 0.05 and abs(dy[5]) < 1e-12


def test_a_loop_edge_is_anchored_on_the_scan_that_drew_the_walls():
    g = LoopGraph(AssociationConfig())
    poses = []
    travel = 0.0
    for i in range(120):  # 12 m along x, each scan hitting a wall 2 m to its left
        p = (
            np.array([0.1 * (i % 60), 0.0, 0.0])
            if i < 60
            else np.array([0.1 * (i - 60), 0.05, 0.0])
        )
        poses.append(p)
        travel += 0.1
        g.record(np.zeros(3), 0.0, travel, 0.0, 0.0, np.array([[0.0, 2.0]]))
    # The window at scan 119 sees the wall at x = 2.5: drawn by scan 25 (and 85, too recent).
    ends = np.array([[2.5, 2.0]])
    edge = g.loop_edge(119, np.array([2.5, 0.0, 0.0]), np.eye(3) * 0.01, poses, ends)
    assert edge is not None
    a, b, z, cov = edge
    assert b == 119 and abs(a - 25) <= 2
    np.testing.assert_allclose(z, relative(poses[a], np.array([2.5, 0.0, 0.0])), atol=1e-12)
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    g.add_loop(edge)
    assert a in g.scans and 119 in g.scans


def _run(pose_graph: bool) -> SampleAssociation:
    truth = truth_path(22.0)
    scans = ir_scans(truth, 1)
    est = drifted(truth, 1.05)
    da = SampleAssociation(MOUNTS, AssociationConfig(pose_graph=pose_graph), GRID, seed=1)
    for h, s in zip(est, scans, strict=True):
        da.step(h, s)
    return da


def test_finish_solves_the_graph_or_keeps_the_map_and_says_why():
    off = _run(False)
    before = off.grid
    assert off.finish() is before and off.graph_outcome == "off"
    on = _run(True)
    traj, grid = on.trajectory.copy(), on.grid
    occ = int((grid.trinary() == 1).sum())
    out = on.finish()
    assert on.graph_outcome.startswith(("re-posed", "kept", "no loop edge"))
    if on.graph_outcome.startswith("re-posed"):
        assert out is on.grid and out is not grid
        assert int((out.trinary() == 1).sum()) <= occ
        assert len(on.trajectory) == len(traj)
        assert not np.allclose(on.trajectory, traj)
    else:
        assert out is grid
        np.testing.assert_array_equal(on.trajectory, traj)
    # The same poses either way before finish(): the graph only records.
    np.testing.assert_array_equal(off.trajectory, traj)
    assert math.isfinite(float(np.sum(on.trajectory)))


def test_a_rebase_keeps_what_each_check_found_on_the_new_poses():
    g = LoopGraph(AssociationConfig())
    old = [np.array([0.0, 0.0, 0.0]), np.array([5.0, 1.0, 0.5])]
    found = compose(relative(old[0], old[1]), np.array([0.1, -0.05, 0.02]))
    g.loops.append((0, 1, found, np.eye(3)))
    new = [np.array([0.0, 0.0, 0.0]), np.array([5.2, 0.4, 0.45])]
    g.rebase(old, new)
    z = g.loops[0][2]
    np.testing.assert_allclose(relative(relative(new[0], new[1]), z), [0.1, -0.05, 0.02],
                               atol=1e-12)  # fmt: skip
