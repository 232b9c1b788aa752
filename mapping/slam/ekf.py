"""The EKF-SLAM filter: joint vehicle + 2-D landmark state (slam-ekf.txt §3.1, §4.2).

State ``[x, y, theta, m1x, m1y, ..., mnx, mny]`` with covariance P. P is stored as an
N x N C-ordered array of which only the upper triangle (and the whole 3x3 vehicle block)
is kept: P is symmetric, and updating one triangle in place halves the work of the
O(N^2) step. Every read of P goes through that triangle (:meth:`EkfSlam._columns`).

- Prediction (§4.2.2, the block form after eq. 15): only the vehicle block is
  propagated, ``Pvv <- F Pvv F' + G Q G'`` and ``Pvm <- F Pvm``; the joint Jacobian
  ``[[F, 0], [0, I]]`` is never built. Both motion models have
  ``F = [[1, 0, a], [0, 1, b], [0, 0, 1]]`` (the position moves by an amount that depends
  on the heading only), so F Pvv F' is written out in floats, the pose and Pvv are kept as
  Python floats between scans (no numpy array per 40 Hz step), and the product
  ``Phi = F_k ... F_1`` of consecutive predictions is the sum of their (a, b). It is
  applied lazily, ``Pvm <- Phi Pvm`` once when Pvm is next needed (O(n) per scan).
- Update (§4.2.3): H of an observation has non-zeros only in the vehicle columns and in
  the two columns of its landmark, so ``P H' = P[:, v] Hv' + P[:, mi] Hm'`` costs O(N) per
  observation and ``P <- P - K S K' = P - V' V`` with ``V = L^-1 (P H')'``, ``S = L L'``
  O(N^2): a symmetric rank-2k update, done in place on the stored triangle by BLAS
  ``dsyrk`` (no N x N temporary); all observations of a scan are processed as one batch.
- Augmentation (§4.2.4): ``m = g(xv, z)``, new cross-covariances ``Gx P[v, :]`` and
  new block ``Gx Pvv Gx' + Gz R Gz'`` (O(N) per new landmark; the arrays grow once per
  call, O(N^2)).
- Gating support: innovation covariances of every landmark at once, vectorised (O(n)).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
from scipy.linalg import blas, lapack

from mapping.slam.models import HALF_PI, Step, inverse_observe, observe
from numerics.angles import wrap, wrap_angle

_PAIR = np.array([[0], [1]])


class MotionModel(Protocol):
    """A planar motion model: :meth:`step` in floats (what the filter calls) and
    :meth:`predict` with arrays (the same numbers; for tests and other callers)."""

    control_dim: int

    def predict(
        self, xv: np.ndarray, u: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...

    def step(self, x: float, y: float, th: float, u0: float, u1: float, dt: float) -> Step: ...


class EkfSlam:
    """EKF-SLAM over a motion model (Ackermann or unicycle) and range-bearing landmarks.

    Parameters: ``model`` (see :class:`MotionModel`), initial pose ``x0`` (3,) and
    covariance ``p0`` (3x3), observation noise ``r`` (2x2, range m^2 / bearing rad^2),
    ``bearing_offset`` (pi/2 for the paper's laser, 0 for 0-rad-ahead sensors).
    """

    def __init__(
        self,
        model: MotionModel,
        x0: np.ndarray | None = None,
        p0: np.ndarray | None = None,
        r: np.ndarray | None = None,
        bearing_offset: float = HALF_PI,
    ) -> None:
        self.model = model
        self.bearing_offset = float(bearing_offset)
        self.r = np.diag([0.25**2, np.deg2rad(1.0) ** 2]) if r is None else np.asarray(r, float)
        if self.r.shape != (2, 2):
            raise ValueError(f"r must be 2x2, got shape {self.r.shape}")
        x0 = np.zeros(3) if x0 is None else np.asarray(x0, float)
        p0 = np.zeros((3, 3)) if p0 is None else np.asarray(p0, float)
        self._x = np.zeros(3)  # the state, length N
        # P (N x N: upper triangle and vehicle block, module doc) is a view of the front of
        # a flat buffer; augmentation copies it into the spare buffer, grown when needed
        self._buf = np.zeros(9)
        self._spare = np.zeros(0)
        self._p = self._buf.reshape(3, 3)
        # the vehicle pose and the 6 entries of Pvv as floats; newer than _x/_p when _stale
        self._pose = (float(x0[0]), float(x0[1]), wrap_angle(float(x0[2])))
        self._pvv = (p0[0, 0], p0[0, 1], p0[0, 2], p0[1, 1], p0[1, 2], p0[2, 2])
        self._pvv = tuple(map(float, self._pvv))
        self._stale = True
        self._phi = (0.0, 0.0)  # pending F product: [[1, 0, a], [0, 1, b], [0, 0, 1]]
        self._n = 0  # landmarks
        self.ids: list[int] = []  # landmark id per slot
        self._next_id = 0

    # ---------------------------------------------------------------- views
    @property
    def size(self) -> int:
        """Length N = 3 + 2n of the joint state."""
        return 3 + 2 * self._n

    @property
    def n_landmarks(self) -> int:
        return self._n

    @property
    def vehicle(self) -> np.ndarray:
        """Vehicle pose (x, y, theta) (a copy)."""
        return np.array(self._pose)

    @property
    def pose(self) -> tuple[float, float, float]:
        """Vehicle pose (x, y, theta) as floats (no array)."""
        return self._pose

    @property
    def vehicle_cov(self) -> np.ndarray:
        p00, p01, p02, p11, p12, p22 = self._pvv
        return np.array([[p00, p01, p02], [p01, p11, p12], [p02, p12, p22]])

    @property
    def landmarks(self) -> np.ndarray:
        """Landmark positions (n, 2) (a copy)."""
        return self._x[3:].reshape(-1, 2).copy()

    @property
    def state(self) -> np.ndarray:
        self._sync()
        return self._x.copy()

    @property
    def covariance(self) -> np.ndarray:
        """The full joint covariance (a copy; O(N^2))."""
        self._sync()
        upper = np.triu(self._p)
        return upper + np.triu(upper, 1).T

    def landmark_covariances(self) -> np.ndarray:
        """Marginal 2x2 covariance of every landmark, (n, 2, 2)."""
        self._sync()
        i = 3 + 2 * np.arange(self._n)
        p = self._p
        out = np.empty((self._n, 2, 2))
        out[:, 0, 0] = p[i, i]
        out[:, 0, 1] = out[:, 1, 0] = p[i, i + 1]
        out[:, 1, 1] = p[i + 1, i + 1]
        return out

    def _rows(self, rows: np.ndarray) -> np.ndarray:
        """P[rows, :] (len(rows), N) from the stored triangle: each row from its diagonal
        on, the columns before it from the column of the same index (P is symmetric)."""
        p = self._p
        return np.where(np.arange(len(p)) >= rows[:, None], p[rows, :], p[:, rows].T)

    # ---------------------------------------------------------------- predict
    def predict(self, u: np.ndarray, dt: float, q: np.ndarray) -> None:
        """Time update with control ``u`` over ``dt`` s; ``q`` = control covariance (2x2)."""
        x, y, th = self._pose
        x, y, th, a, b, g00, g01, g10, g11, g20, g21 = self.model.step(
            x, y, th, float(u[0]), float(u[1]), float(dt)
        )
        (q00, q01), (q10, q11) = np.asarray(q, float).tolist()
        self._pose = (x, y, wrap_angle(th))
        # F Pvv F' with F = I + a e0 e2' + b e1 e2'
        p00, p01, p02, p11, p12, p22 = self._pvv
        r00, r01, r02 = p00 + a * p02, p01 + a * p12, p02 + a * p22
        r11, r12 = p11 + b * p12, p12 + b * p22
        # + G Q G' (h = G Q, row by row)
        h00, h01 = g00 * q00 + g01 * q10, g00 * q01 + g01 * q11
        h10, h11 = g10 * q00 + g11 * q10, g10 * q01 + g11 * q11
        h20, h21 = g20 * q00 + g21 * q10, g20 * q01 + g21 * q11
        self._pvv = (
            r00 + a * r02 + h00 * g00 + h01 * g01,
            r01 + b * r02 + h00 * g10 + h01 * g11,
            r02 + h00 * g20 + h01 * g21,
            r11 + b * r12 + h10 * g10 + h11 * g11,
            r12 + h10 * g20 + h11 * g21,
            p22 + h20 * g20 + h21 * g21,
        )
        self._stale = True
        if self._n:
            pa, pb = self._phi
            self._phi = (pa + a, pb + b)

    def _sync(self) -> None:
        """Write the float pose and Pvv into the arrays and apply the accumulated F
        product to the vehicle-landmark cross-covariance (rows 0-2 of the triangle)."""
        if not self._stale:
            return
        self._stale = False
        self._x[:3] = self._pose
        p00, p01, p02, p11, p12, p22 = self._pvv
        self._p[:3, :3] = ((p00, p01, p02), (p01, p11, p12), (p02, p12, p22))
        a, b = self._phi
        if self._n and (a or b):
            p = self._p
            row2 = p[2, 3:]
            p[0, 3:] += a * row2
            p[1, 3:] += b * row2
        self._phi = (0.0, 0.0)

    def _load(self) -> None:
        """Read the pose and Pvv back after the arrays changed (an update)."""
        x, p = self._x, self._p
        self._pose = (float(x[0]), float(x[1]), float(x[2]))
        self._pvv = tuple(p[[0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2]].tolist())
        p[1, 0], p[2, 0], p[2, 1] = p[0, 1], p[0, 2], p[1, 2]

    # ---------------------------------------------------------------- gating support
    def predict_observations(
        self, idx: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Predicted z (k, 2), Hv (k, 2, 3), Hm (k, 2, 2) and innovation covariances
        S (k, 2, 2) (with R) of landmarks ``idx`` (all by default), vectorised."""
        self._sync()
        idx = np.arange(self._n) if idx is None else np.asarray(idx, dtype=int)
        z, hv, hm = self._observe(idx)
        # With the range-bearing model's Hv = [-Hm | (0, -1)'], H x = Hm (m - p) - theta:
        # S = Hm D Hm' - Hm e t - (Hm e t)' + P_tt + R with D = Cov(m - p), e = Cov(m - p, theta)
        c = 3 + 2 * idx
        p = self._p
        (p00, p01, p02), (_, p11, p12), (_, _, p22) = p[:3, :3].tolist()
        vx, vy = p[:3, c], p[:3, c + 1]  # cross-covariances of the vehicle with mx, my
        d00 = p[c, c] - 2.0 * vx[0] + p00
        d01 = p[c, c + 1] - vy[0] - vx[1] + p01
        d11 = p[c + 1, c + 1] - 2.0 * vy[1] + p11
        e0, e1 = vx[2] - p02, vy[2] - p12
        a0, a1, b0, b1 = hm[:, 0, 0], hm[:, 0, 1], hm[:, 1, 0], hm[:, 1, 1]
        da0, da1 = d00 * a0 + d01 * a1, d01 * a0 + d11 * a1  # D a'
        db0, db1 = d00 * b0 + d01 * b1, d01 * b0 + d11 * b1  # D b'
        s = np.empty((len(idx), 2, 2))
        (r00, r01), (r10, r11) = self.r.tolist()
        s[:, 0, 0] = a0 * da0 + a1 * da1 + r00
        s01 = a0 * db0 + a1 * db1 - (a0 * e0 + a1 * e1)
        s[:, 0, 1] = s01 + r01
        s[:, 1, 0] = s01 + r10
        s[:, 1, 1] = b0 * db0 + b1 * db1 - 2.0 * (b0 * e0 + b1 * e1) + p22 + r11
        return z, hv, hm, s

    def joint_innovation_covariance(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted z (k, 2) and the joint covariance H P H' (2k, 2k) of landmarks ``idx``
        (without R), for joint compatibility tests. O(k N + k^2)."""
        self._sync()
        idx = np.asarray(idx, dtype=int)
        z, hv, hm = self._observe(idx)
        rows, hl, hp = self._hp(idx, hv, hm)
        return z, self._hph(rows, hl, hp)

    def _observe(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        m = self._x[3:].reshape(-1, 2)[idx]
        return observe(self._x[:3], m, self.bearing_offset)

    def _hp(
        self, idx: np.ndarray, hv: np.ndarray, hm: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """H P (2k, N) of observations of landmarks ``idx``, with the state indices H
        touches (3 + 2k: the vehicle's, then each landmark's) and H on them (2k, 3 + 2k):
        the rows of P there times a small dense matrix (one BLAS product; H P is P H')."""
        k = len(idx)
        c = 3 + 2 * idx
        rows = np.empty(3 + 2 * k, dtype=np.intp)
        rows[:3] = (0, 1, 2)
        rows[3::2] = c
        rows[4::2] = c + 1
        hl = np.zeros((2 * k, 3 + 2 * k))
        hl[:, :3] = hv.reshape(2 * k, 3)
        two = 2 * np.arange(k)[:, None, None] + _PAIR
        hl[two, 3 + two.transpose(0, 2, 1)] = hm  # observation j's Hm at (2j.., 3 + 2j..)
        return rows, hl, hl @ self._rows(rows)

    @staticmethod
    def _hph(rows: np.ndarray, hl: np.ndarray, hp: np.ndarray) -> np.ndarray:
        s = hp[:, rows] @ hl.T
        return 0.5 * (s + s.T)

    # ---------------------------------------------------------------- update
    def update(
        self,
        z: np.ndarray,
        idx: np.ndarray,
        predicted: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    ) -> float:
        """Batch update with observations z (k, 2) of landmark slots ``idx`` (k,).
        ``predicted``: their (z, Hv, Hm) from :meth:`predict_observations` of the same
        state, if the caller has them (else computed here).

        Returns the normalised innovation squared of the batch.
        """
        idx = np.asarray(idx, dtype=int)
        z = np.atleast_2d(np.asarray(z, float))
        k = len(idx)
        if k == 0:
            return 0.0
        if len(set(idx.tolist())) != k:
            raise ValueError("one landmark observed twice in one update")
        self._sync()
        zp, hv, hm = self._observe(idx) if predicted is None else predicted
        rows, hl, hp = self._hp(idx, hv, hm)
        s = self._hph(rows, hl, hp)
        ar = np.arange(k)
        s.reshape(k, 2, k, 2)[ar, :, ar, :] += self.r  # + blockdiag(R, ..., R)
        nu = z - zp
        nu[:, 1] = wrap(nu[:, 1])
        # S = L L';  V = L^-1 H P  (2k, N);  P <- P - V' V  (a symmetric rank-2k update)
        low = np.linalg.cholesky(s)
        # V' = (H P)' L'^-1, solved in place on the Fortran-ordered (H P)' (N, 2k)
        vt = blas.dtrsm(1.0, low.T, hp.T, side=1, lower=0, overwrite_b=1)
        e, info = lapack.dtrtrs(low.T, nu.ravel(), lower=0, trans=1)
        if info:
            raise np.linalg.LinAlgError("singular innovation covariance")
        self._x += vt @ e
        self._x[2] = wrap(self._x[2])
        pt = self._p.T  # Fortran order: its lower triangle is the stored upper one
        out = blas.dsyrk(-1.0, vt, beta=1.0, c=pt, lower=1, overwrite_c=1)  # P -= V' V
        if not np.may_share_memory(out, pt):  # f2py made a copy after all
            self._p[...] = out.T
        self._load()
        return float(e @ e)

    # ---------------------------------------------------------------- augmentation
    def augment(self, z: np.ndarray) -> list[int]:
        """Add landmarks observed as z (k, 2) from the current pose; returns their ids."""
        z = np.atleast_2d(np.asarray(z, float))
        self._sync()
        n = self.size
        grown = n + 2 * len(z)
        self._grow(grown)
        x, p = self._x, self._p
        new_ids = []
        for zi in z:
            m, gx, gz = inverse_observe(x[:3], zi[None, :], self.bearing_offset)
            gx, gz = gx[0], gz[0]
            cross = gx @ p[:3, :n]  # (2, N)
            p[:n, n : n + 2] = cross.T
            p[n : n + 2, n : n + 2] = gx @ p[:3, :3] @ gx.T + gz @ self.r @ gz.T
            x[n : n + 2] = m[0]
            n += 2
            self._n += 1
            self.ids.append(self._next_id)
            new_ids.append(self._next_id)
            self._next_id += 1
        return new_ids

    def _grow(self, size: int) -> None:
        """State and covariance of ``size`` (>= N): P copied into the spare buffer (grown
        when too small: no fresh pages to fault in at every new landmark), new entries 0."""
        n = self.size
        need = size * size
        spare = self._spare
        if len(spare) < need:
            spare = np.empty(max(need, 2 * len(self._buf)))
        p = spare[:need].reshape(size, size)
        p[:n, :n] = self._p
        p[:n, n:] = 0.0
        p[n:, :] = 0.0
        self._spare, self._buf, self._p = self._buf, spare, p
        x = np.zeros(size)
        x[:n] = self._x
        self._x = x
