"""The EKF-SLAM filter: joint vehicle + 2-D landmark state (slam-ekf.txt §3.1, §4.2).

State ``[x, y, theta, m1x, m1y, ..., mnx, mny]`` with covariance P, stored in arrays with
spare capacity (doubling) so augmentation does not copy P every time.

- Prediction (§4.2.2, the block form after eq. 15): only the vehicle block is
  propagated, ``Pvv <- F Pvv F' + G Q G'`` and ``Pvm <- F Pvm``; the joint Jacobian
  ``[[F, 0], [0, I]]`` is never built. The cross-covariance product is applied lazily:
  the filter accumulates ``Phi = F_k ... F_1`` over consecutive predictions and applies
  ``Pvm <- Phi Pvm`` once when Pvm is next needed (O(n) per scan, not per 40 Hz step).
- Update (§4.2.3): H of an observation has non-zeros only in the vehicle columns and in
  the two columns of its landmark, so ``P H' = P[:, v] Hv' + P[:, mi] Hm'`` costs O(N) per
  observation and ``P <- P - K S K' = P - V' V`` with ``V = L^-1 (P H')'``, ``S = L L'``
  O(N^2) (a symmetric rank-2k product, so P stays exactly symmetric); all observations
  of a scan are processed as one batch.
- Augmentation (§4.2.4): ``m = g(xv, z)``, new cross-covariances ``Gx P[v, :]`` and
  new block ``Gx Pvv Gx' + Gz R Gz'`` (O(N) per new landmark).
- Gating support: innovation covariances of every landmark at once, vectorised (O(n)).
"""

from __future__ import annotations

from typing import Protocol

import numpy as np
import scipy.linalg

from mapping.slam.models import HALF_PI, inverse_observe, observe
from numerics.angles import wrap


class MotionModel(Protocol):
    control_dim: int

    def predict(
        self, xv: np.ndarray, u: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


class EkfSlam:
    """EKF-SLAM over a motion model (Ackermann or unicycle) and range-bearing landmarks.

    Parameters: ``model`` (``predict(xv, u, dt) -> (xv', F, G)``), initial pose ``x0``
    (3,) and covariance ``p0`` (3x3), observation noise ``r`` (2x2, range m^2 / bearing
    rad^2), ``bearing_offset`` (pi/2 for the paper's laser, 0 for 0-rad-ahead sensors).
    """

    def __init__(
        self,
        model: MotionModel,
        x0: np.ndarray | None = None,
        p0: np.ndarray | None = None,
        r: np.ndarray | None = None,
        bearing_offset: float = HALF_PI,
        capacity: int = 64,
    ) -> None:
        self.model = model
        self.bearing_offset = float(bearing_offset)
        self.r = np.diag([0.25**2, np.deg2rad(1.0) ** 2]) if r is None else np.asarray(r, float)
        if self.r.shape != (2, 2):
            raise ValueError(f"r must be 2x2, got shape {self.r.shape}")
        cap = 3 + 2 * max(int(capacity), 1)
        self._x = np.zeros(cap)
        self._p = np.zeros((cap, cap))
        self._x[:3] = np.zeros(3) if x0 is None else np.asarray(x0, float)
        self._x[2] = wrap(self._x[2])
        self._p[:3, :3] = np.zeros((3, 3)) if p0 is None else np.asarray(p0, float)
        self._n = 0  # landmarks
        self._phi = np.eye(3)  # pending F product for the cross-covariance
        self._phi_pending = False
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
        return self._x[:3].copy()

    @property
    def vehicle_cov(self) -> np.ndarray:
        return self._p[:3, :3].copy()

    @property
    def landmarks(self) -> np.ndarray:
        """Landmark positions (n, 2) (a copy)."""
        return self._x[3 : self.size].reshape(-1, 2).copy()

    @property
    def state(self) -> np.ndarray:
        return self._x[: self.size].copy()

    @property
    def covariance(self) -> np.ndarray:
        """The full joint covariance (a copy; O(N^2))."""
        self._flush()
        n = self.size
        return self._p[:n, :n].copy()

    def landmark_covariances(self) -> np.ndarray:
        """Marginal 2x2 covariance of every landmark, (n, 2, 2)."""
        i = 3 + 2 * np.arange(self._n)
        p = self._p
        out = np.empty((self._n, 2, 2))
        out[:, 0, 0] = p[i, i]
        out[:, 0, 1] = p[i, i + 1]
        out[:, 1, 0] = p[i + 1, i]
        out[:, 1, 1] = p[i + 1, i + 1]
        return out

    # ---------------------------------------------------------------- predict
    def predict(self, u: np.ndarray, dt: float, q: np.ndarray) -> None:
        """Time update with control ``u`` over ``dt`` s; ``q`` = control covariance."""
        xv, f, g = self.model.predict(self._x[:3], np.asarray(u, float), float(dt))
        xv[2] = wrap(xv[2])
        self._x[:3] = xv
        pvv = self._p[:3, :3]
        self._p[:3, :3] = f @ pvv @ f.T + g @ q @ g.T
        if self._n:
            self._phi = f @ self._phi
            self._phi_pending = True

    def _flush(self) -> None:
        """Apply the accumulated F product to the vehicle-landmark cross-covariance."""
        if not self._phi_pending:
            return
        n = self.size
        pvm = self._phi @ self._p[:3, 3:n]
        self._p[:3, 3:n] = pvm
        self._p[3:n, :3] = pvm.T
        self._phi = np.eye(3)
        self._phi_pending = False

    # ---------------------------------------------------------------- gating support
    def predict_observations(
        self, idx: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Predicted z (k, 2), Hv (k, 2, 3), Hm (k, 2, 2) and innovation covariances
        S (k, 2, 2) (with R) of landmarks ``idx`` (all by default), vectorised."""
        self._flush()
        idx = np.arange(self._n) if idx is None else np.asarray(idx, dtype=int)
        m = self._x[3 : self.size].reshape(-1, 2)[idx]
        z, hv, hm = observe(self._x[:3], m, self.bearing_offset)
        c = 3 + 2 * idx
        p = self._p
        pvv = p[:3, :3]
        pvm = np.stack([p[:3, c], p[:3, c + 1]], axis=2)  # (3, k, 2)
        pvm = pvm.transpose(1, 0, 2)  # (k, 3, 2)
        pmm = np.empty((len(idx), 2, 2))
        pmm[:, 0, 0] = p[c, c]
        pmm[:, 0, 1] = p[c, c + 1]
        pmm[:, 1, 0] = p[c + 1, c]
        pmm[:, 1, 1] = p[c + 1, c + 1]
        cross = hv @ pvm @ hm.transpose(0, 2, 1)
        s = hv @ pvv @ hv.transpose(0, 2, 1) + cross + cross.transpose(0, 2, 1)
        s += hm @ pmm @ hm.transpose(0, 2, 1) + self.r
        return z, hv, hm, s

    def joint_innovation_covariance(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted z (k, 2) and the joint covariance H P H' (2k, 2k) of landmarks ``idx``
        (without R), for joint compatibility tests. O(k N + k^2)."""
        self._flush()
        idx = np.asarray(idx, dtype=int)
        z, hv, hm = self._observe(idx)
        pht = self._pht(idx, hv, hm)
        return z, self._hph(idx, hv, hm, pht)

    def _observe(self, idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        m = self._x[3 : self.size].reshape(-1, 2)[idx]
        return observe(self._x[:3], m, self.bearing_offset)

    def _pht(self, idx: np.ndarray, hv: np.ndarray, hm: np.ndarray) -> np.ndarray:
        """P H' (N, 2k) from the sparse blocks of H."""
        n = self.size
        p = self._p[:n, :n]
        c = 3 + 2 * idx
        cols = np.stack([c, c + 1], axis=1)  # (k, 2)
        pc = p[:, cols]  # (N, k, 2)
        pht = np.einsum("nc,kjc->nkj", p[:, :3], hv) + np.einsum("nkc,kjc->nkj", pc, hm)
        return pht.reshape(n, -1)

    @staticmethod
    def _hph(idx: np.ndarray, hv: np.ndarray, hm: np.ndarray, pht: np.ndarray) -> np.ndarray:
        k = len(idx)
        c = 3 + 2 * idx
        cols = np.stack([c, c + 1], axis=1)
        a = np.einsum("kjc,ci->kji", hv, pht[:3])
        b = np.einsum("kjc,kci->kji", hm, pht[cols])
        s = (a + b).reshape(2 * k, 2 * k)
        return 0.5 * (s + s.T)

    # ---------------------------------------------------------------- update
    def update(self, z: np.ndarray, idx: np.ndarray) -> float:
        """Batch update with observations z (k, 2) of landmark slots ``idx`` (k,).

        Returns the normalised innovation squared of the batch.
        """
        idx = np.asarray(idx, dtype=int)
        z = np.atleast_2d(np.asarray(z, float))
        if len(idx) == 0:
            return 0.0
        if len(np.unique(idx)) != len(idx):
            raise ValueError("one landmark observed twice in one update")
        self._flush()
        n = self.size
        zp, hv, hm = self._observe(idx)
        pht = self._pht(idx, hv, hm)
        s = self._hph(idx, hv, hm, pht) + np.kron(np.eye(len(idx)), self.r)
        nu = z - zp
        nu[:, 1] = wrap(nu[:, 1])
        nu = nu.ravel()
        # S = L L';  V = L^-1 H P  (2k, N);  P <- P - V' V  (a symmetric rank-2k update)
        low = np.linalg.cholesky(s)
        v = scipy.linalg.solve_triangular(low, pht.T, lower=True, check_finite=False)
        e = scipy.linalg.solve_triangular(low, nu, lower=True, check_finite=False)
        self._x[:n] += v.T @ e
        self._x[2] = wrap(self._x[2])
        self._p[:n, :n] -= v.T @ v
        return float(e @ e)

    # ---------------------------------------------------------------- augmentation
    def augment(self, z: np.ndarray) -> list[int]:
        """Add landmarks observed as z (k, 2) from the current pose; returns their ids."""
        z = np.atleast_2d(np.asarray(z, float))
        self._flush()
        new_ids = []
        for zi in z:
            self._reserve(self._n + 1)
            n = self.size
            m, gx, gz = inverse_observe(self._x[:3], zi[None, :], self.bearing_offset)
            gx, gz = gx[0], gz[0]
            p = self._p
            cross = gx @ p[:3, :n]  # (2, N)
            p[n : n + 2, :n] = cross
            p[:n, n : n + 2] = cross.T
            p[n : n + 2, n : n + 2] = gx @ p[:3, :3] @ gx.T + gz @ self.r @ gz.T
            self._x[n : n + 2] = m[0]
            self._n += 1
            self.ids.append(self._next_id)
            new_ids.append(self._next_id)
            self._next_id += 1
        return new_ids

    def _reserve(self, landmarks: int) -> None:
        need = 3 + 2 * landmarks
        cap = len(self._x)
        if need <= cap:
            return
        new_cap = max(need, 3 + 2 * (2 * (cap - 3) // 2))
        x = np.zeros(new_cap)
        p = np.zeros((new_cap, new_cap))
        n = self.size
        x[:n] = self._x[:n]
        p[:n, :n] = self._p[:n, :n]
        self._x, self._p = x, p
