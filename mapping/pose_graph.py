"""A 2-D pose graph: poses (x, y, theta) tied by relative-pose measurements, solved by
Levenberg-Marquardt with a robust (Cauchy) kernel on the edges that may be wrong.

Graph SLAM's least squares (Grisetti et al., "A Tutorial on Graph-Based SLAM", 2010,
eq. 6-31; Lu & Milios 1997): each edge from node i to node j measures the pose of j in
the frame of i, z = (t_z, theta_z), with information matrix Omega (3 x 3, in the frame of
node i). Its error (eq. 30, with the translation left in node i's frame):

    e_t  = R_i^T (t_j - t_i) - t_z
    e_th = wrap(theta_j - theta_i - theta_z)

and its Jacobians

    de/dx_i = [[-R_i^T, dR_i^T/dtheta_i (t_j - t_i)], [0, 0, -1]]
    de/dx_j = [[ R_i^T, 0],                            [0, 0,  1]]

(``edge_error`` / ``edge_jacobians``; tests/test_pose_graph.py checks them against
finite differences). The normal equations H dx = -b (eq. 18-22) are assembled as a
sparse matrix (3 x 3 blocks per edge), node 0 held fixed (the gauge), and solved by
sparse LU with Levenberg's damping H + lambda diag(H): memory grows with the edges, not
with the square of the nodes. An edge marked ``robust`` (a loop closure)
counts with the Cauchy cost rho(s) = c^2 log(1 + s / c^2) of its squared Mahalanobis
error s (iteratively reweighted: weight 1 / (1 + s / c^2)); c^2 = 11.34, chi-square with
3 degrees of freedom at 99 %, so an edge that fits within its covariance keeps almost
its full weight and one many sigmas off is down-weighted by s / c^2.

A graph of at most :data:`DENSE_NODES` nodes (a run of up to about 100 m) is solved in
dense form by numpy's LU instead: the same normal equations, a few milliseconds, and no
import of scipy.sparse, which costs 0.2-0.3 s (it loads numpy's whole array-API
namespace) at the end of a short replay.

Pure: numpy, and scipy.sparse inside :meth:`PoseGraph.optimize` for a graph beyond
:data:`DENSE_NODES` (imported there: the daemon, which never solves a graph, and a short
replay do not load scipy).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from numerics.angles import wrap, wrap_angles

CAUCHY_C2 = 11.34  # chi-square 3 dof at 99 %


@dataclass(frozen=True)
class Edge:
    """Pose of node ``j`` in the frame of node ``i``: ``z`` (3,), information ``info``
    (3, 3); ``robust``: counted with the Cauchy kernel."""

    i: int
    j: int
    z: np.ndarray
    info: np.ndarray
    robust: bool = False


@dataclass
class Solution:
    poses: np.ndarray  # (N, 3)
    cost: float  # robust cost at the end (half the sum of rho)
    cost0: float  # at the start
    iterations: int
    weights: np.ndarray  # (E,) the kernel's weight of each edge at the end (1 if not robust)


def edge_error(xi: np.ndarray, xj: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The error of an edge (module doc) for poses ``xi``, ``xj`` (..., 3)."""
    c, s = np.cos(xi[..., 2]), np.sin(xi[..., 2])
    dx, dy = xj[..., 0] - xi[..., 0], xj[..., 1] - xi[..., 1]
    return np.stack([c * dx + s * dy - z[..., 0], -s * dx + c * dy - z[..., 1],
                     wrap_angles(xj[..., 2] - xi[..., 2] - z[..., 2])], axis=-1)  # fmt: skip


def edge_jacobians(xi: np.ndarray, xj: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(de/dx_i, de/dx_j), each (..., 3, 3), of :func:`edge_error`."""
    c, s = np.cos(xi[..., 2]), np.sin(xi[..., 2])
    dx, dy = xj[..., 0] - xi[..., 0], xj[..., 1] - xi[..., 1]
    shape = np.shape(c) + (3, 3)
    a, b = np.zeros(shape), np.zeros(shape)
    a[..., 0, 0], a[..., 0, 1], a[..., 0, 2] = -c, -s, -s * dx + c * dy
    a[..., 1, 0], a[..., 1, 1], a[..., 1, 2] = s, -c, -c * dx - s * dy
    a[..., 2, 2] = -1.0
    b[..., 0, 0], b[..., 0, 1] = c, s
    b[..., 1, 0], b[..., 1, 1] = -s, c
    b[..., 2, 2] = 1.0
    return a, b


@dataclass
class PoseGraph:
    """Nodes (initial poses) and edges; :meth:`optimize` returns the solved poses."""

    poses: list[np.ndarray] = field(default_factory=list)
    edges: list[Edge] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.poses)

    def add_node(self, pose: np.ndarray) -> int:
        p = np.asarray(pose, dtype=float).reshape(3)
        if not np.all(np.isfinite(p)):
            raise ValueError("pose graph: a node's pose must be finite")
        self.poses.append(p.copy())
        return len(self.poses) - 1

    def add_edge(self, i: int, j: int, z: np.ndarray, info: np.ndarray, robust: bool = False):
        n = len(self.poses)
        if not (0 <= i < n and 0 <= j < n) or i == j:
            raise ValueError(f"pose graph: edge {i} -> {j} between unknown or equal nodes")
        z = np.asarray(z, dtype=float).reshape(3)
        info = np.asarray(info, dtype=float).reshape(3, 3)
        if not (np.all(np.isfinite(z)) and np.all(np.isfinite(info))):
            raise ValueError("pose graph: an edge's measurement and information must be finite")
        info = 0.5 * (info + info.T)
        if np.linalg.eigvalsh(info).min() <= 0:
            raise ValueError("pose graph: an edge's information must be positive definite")
        self.edges.append(Edge(i, j, z, info, robust))

    def _arrays(self):
        e = self.edges
        return (np.array([x.i for x in e], dtype=int), np.array([x.j for x in e], dtype=int),
                np.array([x.z for x in e]), np.array([x.info for x in e]),
                np.array([x.robust for x in e], dtype=bool))  # fmt: skip

    def costs(self, poses: np.ndarray, c2: float = CAUCHY_C2):
        """(robust cost, squared Mahalanobis error per edge, kernel weight per edge)."""
        ii, jj, z, info, rob = self._arrays()
        err = edge_error(poses[ii], poses[jj], z)
        s = np.einsum("ei,eij,ej->e", err, info, err)
        rho = np.where(rob, c2 * np.log1p(s / c2), s)
        w = np.where(rob, 1.0 / (1.0 + s / c2), 1.0)
        return 0.5 * float(rho.sum()), s, w

    def optimize(self, iterations: int = 30, c2: float = CAUCHY_C2, tol: float = 1e-6) -> Solution:
        """Levenberg-Marquardt from the nodes' poses, node 0 fixed (module doc)."""
        x = np.array(self.poses, dtype=float)
        n = len(x)
        if n < 2 or not self.edges:
            return Solution(x, 0.0, 0.0, 0, np.ones(len(self.edges)))
        solve = _dense_damped if n <= DENSE_NODES else _sparse_damped()
        ii, jj, z, info, _ = self._arrays()
        cost, _, w = self.costs(x, c2)
        cost0, lam, done = cost, 1e-4, 0
        for it in range(1, iterations + 1):
            done = it
            err = edge_error(x[ii], x[jj], z)
            a, b = edge_jacobians(x[ii], x[jj])
            om = info * w[:, None, None]
            g = np.zeros(3 * n)
            at_om = np.einsum("eki,ekl->eil", a, om)
            bt_om = np.einsum("eki,ekl->eil", b, om)
            blocks = ((ii, ii, np.einsum("eil,elj->eij", at_om, a)),
                      (ii, jj, np.einsum("eil,elj->eij", at_om, b)),
                      (jj, ii, np.einsum("eil,elj->eij", bt_om, a)),
                      (jj, jj, np.einsum("eil,elj->eij", bt_om, b)))  # fmt: skip
            r3 = np.arange(3)
            rows, cols, vals = [], [], []
            for p, q, blk in blocks:
                rows.append(np.broadcast_to(3 * p[:, None, None] + r3[None, :, None], blk.shape))
                cols.append(np.broadcast_to(3 * q[:, None, None] + r3[None, None, :], blk.shape))
                vals.append(blk)
            np.add.at(g, 3 * ii[:, None] + r3, np.einsum("eil,el->ei", at_om, err))
            np.add.at(g, 3 * jj[:, None] + r3, np.einsum("eil,el->ei", bt_om, err))
            entries = (np.concatenate([v.ravel() for v in vals]),
                       np.concatenate([r.ravel() for r in rows]),
                       np.concatenate([c.ravel() for c in cols]))  # fmt: skip
            normal = solve(entries, 3 * n)
            gf = g[3:]
            improved = False
            for _ in range(10):
                dx = normal(lam, -gf)
                if dx is None:  # the damped matrix is singular
                    lam *= 10.0
                    continue
                if not np.all(np.isfinite(dx)):
                    lam *= 10.0
                    continue
                xn = x.copy()
                xn[1:] += dx.reshape(-1, 3)
                xn[:, 2] = wrap(xn[:, 2])
                cn, _, wn = self.costs(xn, c2)
                if cn <= cost:
                    step = float(np.abs(dx).max())
                    rel = (cost - cn) / max(cost, 1e-12)
                    x, cost, w = xn, cn, wn
                    lam = max(lam / 3.0, 1e-9)
                    improved = True
                    break
                lam *= 10.0
            if not improved or step < tol or rel < 1e-9:
                break
        return Solution(x, cost, cost0, done, w)


DENSE_NODES = 150  # at most this many nodes: numpy's dense LU (a 447-square matrix, ~2 ms a solve)


def _dense_damped(entries: tuple[np.ndarray, np.ndarray, np.ndarray], size: int) -> Any:
    """The normal matrix summed from its 3 x 3 blocks, node 0's rows and columns dropped
    (the gauge); returns ``solve(lam, rhs)`` of ``(H + lam diag(H)) dx = rhs``, None when
    singular."""
    vals, rows, cols = entries
    h = np.zeros((size, size))
    np.add.at(h, (rows, cols), vals)
    hf = h[3:, 3:]
    diag = np.maximum(np.diagonal(hf).copy(), 1e-9)
    idx = np.diag_indices_from(hf)

    def solve(lam: float, rhs: np.ndarray) -> np.ndarray | None:
        m = hf.copy()
        m[idx] += lam * diag
        try:
            return np.linalg.solve(m, rhs)
        except np.linalg.LinAlgError:
            return None

    return solve


def _sparse_damped() -> Any:
    """As :func:`_dense_damped`, in sparse form (SuperLU), for a long run's graph."""
    from scipy import sparse  # only here: a graph beyond DENSE_NODES
    from scipy.sparse.linalg import spsolve

    def build(entries: tuple[np.ndarray, np.ndarray, np.ndarray], size: int) -> Any:
        vals, rows, cols = entries
        h = sparse.coo_matrix((vals, (rows, cols)), shape=(size, size)).tocsc()
        hf = h[3:, 3:]
        diag = np.maximum(hf.diagonal(), 1e-9)

        def solve(lam: float, rhs: np.ndarray) -> np.ndarray | None:
            try:
                return spsolve(hf + sparse.diags(lam * diag, format="csc"), rhs)
            except RuntimeError:  # SuperLU: the matrix is singular
                return None

        return solve

    return build
