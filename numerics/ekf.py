"""The pieces of an extended Kalman filter step, ekf-vs-cp.txt eq. (3)-(4).

Prediction of the covariance through the motion model's Jacobians (eq. 4, A = F, W = G):
    P' = F P F^T + G Q G^T
Update on a measurement with innovation nu = z - h(x), Jacobian H and noise R:
    S = H P H^T + R,    NIS = nu^T S^-1 nu,    K = P H^T S^-1,
    x' = x + K nu,      P' = (I - K H) P (I - K H)^T + K R K^T   (Joseph form).
The innovation and the update are separate so that a filter can gate on the NIS before
it changes anything. Whatever a filter adds (wrapping, symmetrising, repairing a
covariance, counting) stays with the filter.
"""

from __future__ import annotations

import numpy as np


def predict_covariance(p: np.ndarray, f: np.ndarray, g: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Eq. (4): F P F^T + G Q G^T."""
    return f @ p @ f.T + g @ q @ g.T


def innovation(
    p: np.ndarray, h: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(P H^T, S, S^-1) of a measurement with Jacobian H and noise covariance R."""
    ph = p @ h.T
    s = h @ ph + r
    return ph, s, np.linalg.inv(s)


def nis(nu: np.ndarray, s_inv: np.ndarray) -> float:
    """Normalised innovation squared nu^T S^-1 nu (the squared Mahalanobis distance)."""
    return float(nu @ s_inv @ nu)


def joseph_update(
    x: np.ndarray,
    p: np.ndarray,
    nu: np.ndarray,
    h: np.ndarray,
    r: np.ndarray,
    ph: np.ndarray,
    s_inv: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """(x', P') of the Kalman update in Joseph form, from :func:`innovation`'s P H^T, S^-1."""
    k = ph @ s_inv
    x = x + k @ nu
    ikh = np.eye(p.shape[0]) - k @ h
    return x, ikh @ p @ ikh.T + k @ r @ k.T
