"""Measurement update, gating and counters shared by the pose EKF (ekf-vs-cp eq. 4).

- :func:`chi2_gate`: the chi-square quantile a measurement's NIS is compared with;
- :func:`joseph_update`: the gated Kalman update: NIS and Joseph form
  P = (I - K H) P (I - K H)^T + K R K^T from numerics.ekf, then symmetrised, with a
  Cholesky check that repairs a covariance that lost positive definiteness (eigenvalues
  clipped at 1e-12);
- :class:`UpdateResult`, :class:`EkfCounters`: what one measurement did, and the counts
  the daemon publishes as diagnostics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from numerics import ekf
from numerics.chi2 import chi2_ppf


def chi2_gate(probability: float | None, dof: int) -> float:
    """Chi-square gate on the NIS for ``dof`` dimensions at ``probability`` (None: off)."""
    if probability is None:
        return math.inf
    return chi2_ppf(probability, dof)


def is_pd(m: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(m)
    except np.linalg.LinAlgError:
        return False
    return True


def repair_pd(m: np.ndarray) -> np.ndarray:
    w, v = np.linalg.eigh(0.5 * (m + m.T))
    out = (v * np.maximum(w, 1e-12)) @ v.T
    return 0.5 * (out + out.T)


@dataclass(frozen=True, slots=True)
class UpdateResult:
    """What one measurement did: accepted or gated out, its NIS and dimension."""

    kind: str
    accepted: bool
    nis: float
    dof: int


def joseph_update(
    x: np.ndarray, p: np.ndarray, nu: np.ndarray, hj: np.ndarray, r: np.ndarray, gate: float
) -> tuple[np.ndarray, np.ndarray, float, bool, bool]:
    """(x', P', NIS, accepted, repaired); x, P unchanged when gated out (NIS > gate)."""
    ph, _, s_inv = ekf.innovation(p, hj, r)
    nis = ekf.nis(nu, s_inv)
    if nis > gate:
        return x, p, nis, False, False
    x, pj = ekf.joseph_update(x, p, nu, hj, r, ph, s_inv)
    pj = 0.5 * (pj + pj.T)
    repaired = not is_pd(pj)
    if repaired:
        pj = repair_pd(pj)
    return x, pj, nis, True, repaired


@dataclass
class EkfCounters:
    gps: int = 0
    predictions: int = 0
    gyro_fused: int = 0
    gyro_merges: int = 0
    odometry_heading_rejected: int = 0
    gps_updates: int = 0
    gps_rejected: int = 0
    gps_no_fix: int = 0
    gps_init: int = 0
    heading_updates: int = 0
    heading_rejected: int = 0
    out_of_order_gps: int = 0
    gps_timeouts: int = 0
    covariance_repairs: int = 0
    bad_input: int = 0
    resets: int = 0
    extra: dict[str, int] = field(default_factory=dict)
